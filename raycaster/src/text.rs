//! Wording shared by the tools' messages.

/// `n` and `noun`, plural unless `n` is 1 ("1 brick", "729 bricks").
pub fn counted(n: u64, noun: &str) -> String {
    if n == 1 {
        format!("1 {noun}")
    } else {
        format!("{n} {noun}s")
    }
}

#[cfg(test)]
mod tests {
    use super::counted;

    #[test]
    fn one_is_singular_and_every_other_count_plural() {
        assert_eq!(counted(1, "bin"), "1 bin");
        assert_eq!(counted(0, "bin"), "0 bins");
        assert_eq!(counted(16, "bin"), "16 bins");
    }
}
