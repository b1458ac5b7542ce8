//! Wording shared by the tools' messages.

/// `n` and `noun`, plural unless `n` is 1 ("1 brick", "729 bricks").
pub fn counted(n: u64, noun: &str) -> String {
    if n == 1 {
        format!("1 {noun}")
    } else {
        format!("{n} {noun}s")
    }
}

/// `text` without the byte-order mark some editors put at the start of a UTF-8
/// file (Windows Notepad): the tools' text files read the same with or
/// without it.
pub fn without_bom(text: &str) -> &str {
    text.strip_prefix('\u{feff}').unwrap_or(text)
}

#[cfg(test)]
mod tests {
    use super::{counted, without_bom};

    #[test]
    fn a_byte_order_mark_is_dropped_and_only_it() {
        assert_eq!(without_bom("\u{feff}point 0"), "point 0");
        assert_eq!(without_bom("point 0"), "point 0");
        assert_eq!(without_bom("a\u{feff}"), "a\u{feff}");
    }

    #[test]
    fn one_is_singular_and_every_other_count_plural() {
        assert_eq!(counted(1, "bin"), "1 bin");
        assert_eq!(counted(0, "bin"), "0 bins");
        assert_eq!(counted(16, "bin"), "16 bins");
    }
}
