//! Error text for people: the chain of causes said once.

use std::error::Error;

/// The error and its causes joined by `: `, leaving out a cause whose text the
/// message already holds (an error that prints its source, and then the source
/// itself, would otherwise say the same thing twice: "X: X").
pub fn error_text(error: &(dyn Error + 'static)) -> String {
    let mut out = error.to_string();
    let mut cause = error.source();
    while let Some(c) = cause {
        let text = c.to_string();
        if !text.is_empty() && !out.contains(&text) {
            out.push_str(": ");
            out.push_str(&text);
        }
        cause = c.source();
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, thiserror::Error)]
    #[error("cannot read scene a.toml: {source}")]
    struct Echo {
        source: std::io::Error,
    }

    #[derive(Debug, thiserror::Error)]
    #[error("rendering failed")]
    struct Outer(#[source] std::io::Error);

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
