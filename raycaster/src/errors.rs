//! Error text for people: the chain of causes said once.

use std::error::Error;

/// The error and its causes joined by `: `, leaving out a cause whose text the
/// message already holds (an error that prints its source, and then the source
/// itself, would otherwise say the same thing twice: "X: X").
///
/// Trailing newlines (TOML's errors end with one) are dropped, so that what
/// follows the text, a cause or a note, stays on its line.
pub fn error_text(error: &(dyn Error + 'static)) -> String {
    let mut out = error.to_string().trim_end().to_string();
    let mut cause = error.source();
    while let Some(c) = cause {
        let text = c.to_string().trim_end().to_string();
        if !text.is_empty() && !out.contains(&text) {
            out.push_str(": ");
            out.push_str(&text);
        }
        cause = c.source();
    }
    shorten_long_lines(&escape_controls(&out))
}

/// `text` with its control characters but line breaks and tabs written as
/// escapes (`\u{1b}`, `\0`): parsers quote what they failed on, and a
/// broken file's bytes would otherwise reach the terminal as commands
/// (colours, a cleared screen) or vanish (NUL).
fn escape_controls(text: &str) -> String {
    text.chars()
        .map(|c| {
            if c.is_control() && c != '\n' && c != '\t' {
                c.escape_debug().to_string()
            } else {
                c.to_string()
            }
        })
        .collect()
}

/// `text` on one line, for a status line that shows one: the quoted source
/// lines of a parser's message (TOML's `3 | file = 5` and its `|` and `^`
/// lines) are left out, and the other lines joined with `: `, so the reason
/// after the snippet stays in sight.
pub fn one_line(text: &str) -> String {
    let snippet = |line: &str| {
        let rest = line
            .trim_start()
            .trim_start_matches(|c: char| c.is_ascii_digit());
        rest.trim_start().starts_with('|')
    };
    text.lines()
        .filter(|l| !l.trim().is_empty() && !snippet(l))
        .map(str::trim)
        .collect::<Vec<_>>()
        .join(": ")
}

/// Characters of a message line kept: parsers quote the line they failed on,
/// which in a broken file can be megabytes long.
const MAX_LINE_CHARS: usize = 600;

/// Characters kept of the end of a line that is cut: where a message says
/// what is wrong after what it quotes.
const KEPT_END_CHARS: usize = 150;

/// `text` with each line longer than [`MAX_LINE_CHARS`] cut in the middle,
/// saying how much was left out: its start and its end stay.
fn shorten_long_lines(text: &str) -> String {
    text.split('\n')
        .map(|line| {
            let count = line.chars().count();
            if count <= MAX_LINE_CHARS {
                return line.to_string();
            }
            let head = MAX_LINE_CHARS - KEPT_END_CHARS;
            let start: String = line.chars().take(head).collect();
            let end: String = line.chars().skip(count - KEPT_END_CHARS).collect();
            format!(
                "{start}… ({} characters left out) …{end}",
                count - head - KEPT_END_CHARS
            )
        })
        .collect::<Vec<_>>()
        .join("\n")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn control_characters_of_a_file_quoted_in_a_message_are_escaped() {
        let e = std::io::Error::other(
            "DimSize `10 \u{1b}[31mRED\u{1b}[0m` is not 3 whole numbers\n\tnext\0",
        );
        assert_eq!(
            error_text(&e),
            "DimSize `10 \\u{1b}[31mRED\\u{1b}[0m` is not 3 whole numbers\n\tnext\\0"
        );
    }

    #[derive(Debug, thiserror::Error)]
    #[error("cannot read scene a.toml: {source}")]
    struct Echo {
        source: std::io::Error,
    }

    #[derive(Debug, thiserror::Error)]
    #[error("rendering failed")]
    struct Outer(#[source] std::io::Error);

    #[test]
    fn a_megabyte_line_quoted_by_a_parser_is_cut() {
        let long = format!("line 1: `{}` is not a key\nnext", "x".repeat(1_000_000));
        let e = std::io::Error::other(long);
        let text = error_text(&e);
        assert!(text.len() < 700, "{}", text.len());
        // The start and the reason at the end stay.
        assert!(text.starts_with("line 1: `xxx"), "{text}");
        assert!(
            text.contains("… (999423 characters left out) …xxx"),
            "{text}"
        );
        assert!(text.ends_with("xxx` is not a key\nnext"), "{text}");
        let short = std::io::Error::other("é".repeat(600));
        assert_eq!(error_text(&short), "é".repeat(600));
    }

    #[test]
    fn a_trailing_newline_is_dropped_before_a_cause_or_a_note() {
        let e = std::io::Error::other("missing field `transfer`\n");
        assert_eq!(error_text(&e), "missing field `transfer`");
        let wrapped = Outer(std::io::Error::other("line one\n"));
        assert_eq!(error_text(&wrapped), "rendering failed: line one");
    }

    #[test]
    fn a_parser_message_on_one_line_keeps_its_reason() {
        let toml = "s.toml: session: TOML parse error at line 3, column 8\n  |\n3 | file = 5\n  |        ^\ninvalid type: integer `5`, expected path string\n";
        assert_eq!(
            one_line(toml),
            "s.toml: session: TOML parse error at line 3, column 8: invalid type: integer `5`, expected path string"
        );
        assert_eq!(one_line("one line"), "one line");
    }

    #[test]
    fn each_cause_is_said_once() {
        let e = Echo {
            source: std::io::Error::other("no such file"),
        };
        assert_eq!(error_text(&e), "cannot read scene a.toml: no such file");
        let e = Outer(std::io::Error::other("disk full"));
        assert_eq!(error_text(&e), "rendering failed: disk full");
    }
}
