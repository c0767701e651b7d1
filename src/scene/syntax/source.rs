//! A scene's text as the session reads it: a file read within a size limit and checked to be
//! UTF-8, its line breaks as editors show them, and look-alike characters refused before
//! parsing. Nothing here knows a statement.

use std::path::Path;

use super::error::{ErrorKind, SceneError};

/// The largest scene file read, in bytes.
pub const MAX_SCENE_BYTES: u64 = 4 << 20;

/// Reads a scene file: at most [`MAX_SCENE_BYTES`], valid UTF-8, or a clear error. The limit
/// holds for anything the path names (a device such as `/dev/zero`, a pipe): the read
/// itself stops one byte past it, so no input can make it allocate more.
pub fn read_scene(path: &Path) -> Result<String, SceneError> {
    use std::io::Read;
    let cannot = |e: std::io::Error| SceneError::new(ErrorKind::Io, format!("cannot read `{}`: {e}", path.display()));
    let too_large = |size: String| {
        SceneError::new(
            ErrorKind::TooLarge,
            format!("`{}` is {size}; scene files are limited to {} MB", path.display(), MAX_SCENE_BYTES >> 20),
        )
        .hint("a scene is a short list of statements; generate large inputs as data files")
    };
    let meta = std::fs::metadata(path).map_err(cannot)?;
    if meta.is_dir() {
        return Err(SceneError::new(ErrorKind::Io, format!("cannot read `{}`: it is a directory", path.display()))
            .hint("give the path of a scene file"));
    }
    if meta.is_file() && meta.len() > MAX_SCENE_BYTES {
        return Err(too_large(format!("{:.1} MB", meta.len() as f64 / 1e6)));
    }
    let mut bytes = Vec::new();
    std::fs::File::open(path).and_then(|f| f.take(MAX_SCENE_BYTES + 1).read_to_end(&mut bytes)).map_err(cannot)?;
    if bytes.len() as u64 > MAX_SCENE_BYTES {
        return Err(too_large("not a regular file and longer than the limit".to_string()));
    }
    // A byte-order mark some editors write is not part of the scene.
    if bytes.starts_with("\u{feff}".as_bytes()) {
        bytes.drain(..3);
    }
    String::from_utf8(bytes).map_err(|e| {
        let at = e.utf8_error().valid_up_to();
        let bytes = e.as_bytes();
        let line = bytes[..at].iter().filter(|&&b| b == b'\n').count() + 1;
        let col = bytes[..at].iter().rev().take_while(|&&b| b != b'\n').count() + 1;
        SceneError::new(
            ErrorKind::Encoding,
            format!("`{}` is not UTF-8: invalid byte 0x{:02x} at line {line}, column {col}", path.display(), bytes[at]),
        )
        .hint("save the scene as UTF-8 (Greek letters such as θ must be UTF-8 encoded)")
    })
}

/// Refuses a look-alike character (Cyrillic, full-width, combining mark) anywhere in a scene
/// but comments and quoted paths, at its location (the command line does the
/// same for its arguments).
pub(in crate::scene) fn refuse_lookalikes(text: &str) -> Result<(), SceneError> {
    let (mut in_comment, mut in_quote) = (false, false);
    for (i, c) in text.char_indices() {
        match c {
            '\n' => (in_comment, in_quote) = (false, false),
            '#' if !in_quote => in_comment = true,
            '"' if !in_comment => in_quote = !in_quote,
            _ if in_comment || in_quote => {}
            _ => {
                if let Some(what) = crate::parse::lookalike_kind(c) {
                    return Err(SceneError::new(ErrorKind::Syntax, crate::parse::lookalike_message(c, what))
                        .at((i, i + c.len_utf8()))
                        .hint(crate::parse::LOOKALIKE_HINT));
                }
            }
        }
    }
    Ok(())
}

/// The scene's text with every lone carriage return (old Mac line ends) read as a line break,
/// as editors show it; `\r\n` stays. The length is unchanged, so spans stay true.
pub(in crate::scene) fn line_breaks(text: &str) -> std::borrow::Cow<'_, str> {
    if !text.contains('\r') {
        return std::borrow::Cow::Borrowed(text);
    }
    let bytes = text.as_bytes();
    let mut out = String::with_capacity(text.len());
    for (i, c) in text.char_indices() {
        if c == '\r' && bytes.get(i + 1) != Some(&b'\n') {
            out.push('\n');
        } else {
            out.push(c);
        }
    }
    std::borrow::Cow::Owned(out)
}
