//! Keyboard shortcuts of the canvas: what a key press does.

use crate::navigation::AxisView;

/// The help line the window shows under the canvas.
pub(crate) const HELP: &str = "keys: R reset view · 1/2/3 or X/Y/Z view from +x/+y/+z (shift: −) · S or Ctrl+S screenshot · Ctrl+Z/Y undo/redo curve edits";

/// What a key does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Shortcut {
    /// Back to the default view.
    Reset,
    /// A view along an axis.
    Axis(AxisView),
    /// Save the frame on screen as a new PNG file.
    Screenshot,
    /// Take back the last transfer-function edit.
    Undo,
    /// Make the last undone transfer-function edit again.
    Redo,
}

/// The shortcut of a key press: `text` is the key's text as Slint gives it
/// (shift makes letters upper case), `control` whether Ctrl is held.
pub(crate) fn shortcut(text: &str, control: bool) -> Option<Shortcut> {
    let mut chars = text.chars();
    let (Some(c), None) = (chars.next(), chars.next()) else {
        return None;
    };
    if control {
        return match c {
            's' | 'S' => Some(Shortcut::Screenshot),
            'z' => Some(Shortcut::Undo),
            // Ctrl+Shift+Z, as most editors.
            'Z' | 'y' | 'Y' => Some(Shortcut::Redo),
            _ => None,
        };
    }
    let negative = c.is_uppercase();
    let axis = |label: char| -> Option<Shortcut> {
        let sign = if negative { '-' } else { '+' };
        AxisView::parse(&format!("{sign}{label}")).map(Shortcut::Axis)
    };
    match c {
        'r' | 'R' => Some(Shortcut::Reset),
        's' | 'S' => Some(Shortcut::Screenshot),
        '1' => axis('x'),
        '2' => axis('y'),
        '3' => axis('z'),
        // Shift + 1/2/3 on a US keyboard.
        '!' => AxisView::parse("-x").map(Shortcut::Axis),
        '@' => AxisView::parse("-y").map(Shortcut::Axis),
        '#' => AxisView::parse("-z").map(Shortcut::Axis),
        'x' | 'X' => axis('x'),
        'y' | 'Y' => axis('y'),
        'z' | 'Z' => axis('z'),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_map_to_actions() {
        assert_eq!(shortcut("r", false), Some(Shortcut::Reset));
        assert_eq!(
            shortcut("1", false),
            Some(Shortcut::Axis(AxisView::X { negative: false }))
        );
        assert_eq!(
            shortcut("Y", false),
            Some(Shortcut::Axis(AxisView::Y { negative: true }))
        );
        assert_eq!(
            shortcut("3", false),
            Some(Shortcut::Axis(AxisView::Z { negative: false }))
        );
        assert_eq!(shortcut("s", true), Some(Shortcut::Screenshot));
        assert_eq!(shortcut("s", false), Some(Shortcut::Screenshot));
        assert_eq!(shortcut("z", true), Some(Shortcut::Undo));
        assert_eq!(shortcut("Z", true), Some(Shortcut::Redo));
        assert_eq!(shortcut("y", true), Some(Shortcut::Redo));
        assert_eq!(
            shortcut("z", false),
            Some(Shortcut::Axis(AxisView::Z { negative: false }))
        );
        assert_eq!(shortcut("r", true), None);
        assert_eq!(shortcut("q", false), None);
        assert_eq!(shortcut("", false), None);
        assert_eq!(shortcut("rr", false), None);
    }
}
