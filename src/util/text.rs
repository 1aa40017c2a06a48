//! User text as messages echo it.

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
