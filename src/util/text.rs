//! User text as messages echo it.

use std::path::Path;

/// Longest user text (key, name) echoed in a message, in characters.
pub const ECHO_CHARS: usize = 40;

/// User text as a message echoes it: at most [`ECHO_CHARS`] characters then
/// `...`, with control characters escaped so the message stays one line.
pub fn cut(text: &str) -> String {
    let mut out = String::new();
    for (i, c) in text.chars().enumerate() {
        if i == ECHO_CHARS {
            out.push_str("...");
            break;
        }
        if c.is_control() {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    out
}

/// Longest path echoed in a message whole, in characters; a longer one
/// keeps its first and last half of this.
pub const PATH_ECHO_CHARS: usize = 240;

/// A path as a message echoes it: whole up to [`PATH_ECHO_CHARS`]
/// characters, else its head and its tail (where the file name is) around
/// `...`; control characters escaped, as in [`cut`].
pub fn cut_path(path: &Path) -> String {
    let text = path.to_string_lossy();
    let chars: Vec<char> = text.chars().collect();
    let escape = |part: &[char]| -> String {
        let mut out = String::new();
        for c in part {
            if c.is_control() {
                out.extend(c.escape_default());
            } else {
                out.push(*c);
            }
        }
        out
    };
    if chars.len() <= PATH_ECHO_CHARS {
        return escape(&chars);
    }
    let half = PATH_ECHO_CHARS / 2;
    format!(
        "{}...{}",
        escape(&chars[..half]),
        escape(&chars[chars.len() - half..])
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn long_text_and_paths_are_cut() {
        assert_eq!(cut("key"), "key");
        assert_eq!(cut(&"k".repeat(41)), format!("{}...", "k".repeat(40)));
        assert_eq!(cut("a\nb"), "a\\nb");
        let short = Path::new("/scenes/mesh.obj");
        assert_eq!(cut_path(short), "/scenes/mesh.obj");
        let long = format!("/{}/mesh.obj", "d".repeat(300));
        let shown = cut_path(Path::new(&long));
        assert_eq!(shown.chars().count(), PATH_ECHO_CHARS + 3);
        assert!(
            shown.starts_with("/ddd") && shown.ends_with("ddd/mesh.obj"),
            "{shown}"
        );
    }
}
