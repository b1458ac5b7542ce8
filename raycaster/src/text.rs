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

/// A TOML parse error of `text` in one line, ``line L, column C (`the line`):
/// what`` (the parser's own text quotes the line under a caret, over four
/// lines; the line is kept, its key is often what the message leaves out).
pub fn toml_error(text: &str, error: &toml::de::Error) -> String {
    let message = error.message().trim().replace('\n', " ");
    let Some((line, column, quoted)) = error_place(text, error) else {
        return message;
    };
    if quoted.is_empty() {
        format!("line {line}, column {column}: {message}")
    } else {
        format!("line {line}, column {column} (`{quoted}`): {message}")
    }
}

/// [`toml_error`] for `text` that is not the user's file (a table read from
/// one and written again, whose lines are not the file's): the line quoted,
/// which names the key, without its number.
pub fn toml_error_unnumbered(text: &str, error: &toml::de::Error) -> String {
    let message = error.message().trim().replace('\n', " ");
    match error_place(text, error) {
        Some((_, _, quoted)) if !quoted.is_empty() => format!("`{quoted}`: {message}"),
        _ => message,
    }
}

/// Where in `text` `error` lies: its line and column (from 1) and the line,
/// trimmed and cut to 60 characters.
fn error_place(text: &str, error: &toml::de::Error) -> Option<(usize, usize, String)> {
    /// Characters of the quoted line kept.
    const QUOTED: usize = 60;
    let span = error.span()?;
    let start = span.start.min(text.len());
    let start = (0..=start)
        .rev()
        .find(|&i| text.is_char_boundary(i))
        .unwrap_or(0);
    let before = &text[..start];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().unwrap_or("").chars().count() + 1;
    let quoted = text.lines().nth(line - 1).unwrap_or("").trim();
    let quoted = if quoted.chars().count() > QUOTED {
        format!("{}…", quoted.chars().take(QUOTED).collect::<String>())
    } else {
        quoted.to_string()
    };
    Some((line, column, quoted))
}

/// A file's declared scaling of its stored samples (a NIfTI slope and
/// intercept, a DICOM rescale), said as a `.vol` file's value units are
/// ([`crate::volume::ValueUnits::describe`]): `value = stored × 2 − 1024`.
pub fn scaling_text(slope: f32, intercept: f32) -> String {
    crate::volume::ValueUnits {
        scale: f64::from(slope),
        offset: f64::from(intercept),
        unit: String::new(),
    }
    .describe()
}

/// The first number of TOML `text` that no 32-bit float holds (they are read
/// as `f32`s: `1e300` would be infinity, said as "inf"), as its key (dotted)
/// and what to say of it; `Ok` for text that does not parse (its reader says
/// why). A number too small for an `f32` reads as 0, as on the command line.
pub fn toml_float_range(text: &str) -> Result<(), (String, String)> {
    fn walk(key: &str, value: &toml::Value) -> Result<(), (String, String)> {
        match value {
            toml::Value::Float(v) if v.is_finite() && (*v as f32).is_infinite() => Err((
                key.to_string(),
                format!(
                    "{v:e} is too large (a 32-bit float holds up to {:e})",
                    f32::MAX
                ),
            )),
            toml::Value::Table(t) => t.iter().try_for_each(|(k, v)| {
                let key = if key.is_empty() {
                    k.clone()
                } else {
                    format!("{key}.{k}")
                };
                walk(&key, v)
            }),
            toml::Value::Array(a) => a.iter().try_for_each(|v| walk(key, v)),
            _ => Ok(()),
        }
    }
    match text.parse::<toml::Table>() {
        Ok(table) => walk("", &toml::Value::Table(table)),
        Err(_) => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::{counted, scaling_text, toml_error, without_bom};

    #[test]
    fn toml_errors_are_one_line_with_their_place() {
        #[derive(serde::Deserialize, Debug)]
        #[serde(deny_unknown_fields)]
        #[allow(dead_code)]
        struct File {
            version: u32,
        }
        let text = "version = 1\n# a comment\n  bogus = 3\n";
        let error = toml::from_str::<File>(text).unwrap_err();
        assert!(error.to_string().lines().count() > 1);
        let said = toml_error(text, &error);
        assert!(
            said.starts_with("line 3, column 3 (`bogus = 3`): unknown field `bogus`"),
            "{said}"
        );
        assert_eq!(said.lines().count(), 1);
        // The key, which the parser's message leaves out, is in the line.
        let text = "version = \"one\"";
        let said = toml_error(text, &toml::from_str::<File>(text).unwrap_err());
        assert!(
            said.starts_with("line 1, column 11 (`version = \"one\"`): invalid type"),
            "{said}"
        );
    }

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

    #[test]
    fn a_negative_offset_is_said_with_a_minus() {
        assert_eq!(scaling_text(2.0, -1024.0), "value = stored × 2 − 1024");
        assert_eq!(scaling_text(0.5, 10.0), "value = stored × 0.5 + 10");
        // (f32 numbers as written, not as their f64 widening: 0.001, not
        // 0.0010000000474974513.)
        assert_eq!(scaling_text(0.001, -0.25), "value = stored × 0.001 − 0.25");
    }
}
