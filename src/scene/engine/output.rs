//! Output files are written to a temporary file in the destination's directory and renamed
//! into place only when the scene (or the REPL entry) has succeeded, so a failing scene
//! leaves no partial or stale-looking output behind, and a reader never sees half a file.

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use crate::scene::syntax::error::{ErrorKind, SceneError};

/// Files written so far and not yet moved into place, the paths claimed by the outputs of
/// the current scene or REPL entry, and the output lines that announce them.
pub struct Staging {
    staged: Vec<(PathBuf, PathBuf)>,
    counter: usize,
    claimed: HashSet<PathBuf>,
    announced: Vec<usize>,
}

impl Staging {
    /// An empty staging area. (`_immediate` is kept for symmetry: the REPL commits after
    /// every entry, a scene once at the end; both go through [`Staging::commit`].)
    pub fn new(_immediate: bool) -> Staging {
        Staging { staged: Vec::new(), counter: 0, claimed: HashSet::new(), announced: Vec::new() }
    }

    /// A temporary path next to `target`, created now so that an unwritable destination is
    /// reported before any work is done. The temporary name keeps the extension (image
    /// encoders choose the format from it).
    pub fn stage(&mut self, target: &Path) -> Result<PathBuf, SceneError> {
        let dir = match target.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let Some(file) = target.file_name().and_then(|f| f.to_str()) else {
            return Err(SceneError::new(ErrorKind::Io, format!("`{}` is not a file name", target.display())));
        };
        if target.is_dir() {
            return Err(SceneError::new(
                ErrorKind::Io,
                format!("cannot write `{}`: it is a directory", target.display()),
            )
            .hint("give a file name such as `out/phase.svg`"));
        }
        let ext = target.extension().and_then(|e| e.to_str()).unwrap_or("tmp");
        self.counter += 1;
        let tmp = dir.join(format!(".{file}.{}-{}.partial.{ext}", std::process::id(), self.counter));
        crate::cancel::remove_at_exit(&tmp);
        std::fs::File::create(&tmp).map_err(|e| {
            SceneError::new(ErrorKind::Io, format!("cannot write `{}`: {e}", target.display()))
                .label("cannot write here")
                .hint(format!("the directory `{}` must exist and be writable", dir.display()))
        })?;
        self.staged.push((tmp.clone(), target.to_path_buf()));
        Ok(tmp)
    }

    /// Claims `target` for one output of the current unit (a scene, a REPL entry); a path
    /// claimed twice is an error, found before anything runs.
    pub fn claim(&mut self, target: &Path) -> Result<(), SceneError> {
        if self.claimed.insert(target.to_path_buf()) {
            return Ok(());
        }
        Err(SceneError::new(
            ErrorKind::Io,
            format!("two outputs write `{}`; the second would replace the first", target.display()),
        )
        .label("second output to the same file")
        .hint("give each `plot` and `export` its own file name"))
    }

    /// Records that output line `index` announces a staged file.
    pub fn announced(&mut self, index: usize) {
        self.announced.push(index);
    }

    /// The output lines announcing files that were not moved into place (after
    /// [`Staging::abort`] or a failed [`Staging::commit`]), last first, for removal.
    pub fn withdrawn(&mut self) -> Vec<usize> {
        let mut v = std::mem::take(&mut self.announced);
        v.reverse();
        v
    }

    /// Moves every staged file into place.
    pub fn commit(&mut self) -> Result<(), SceneError> {
        self.claimed.clear();
        let staged = std::mem::take(&mut self.staged);
        let mut iter = staged.into_iter();
        while let Some((tmp, target)) = iter.next() {
            let moved = std::fs::rename(&tmp, &target);
            crate::cancel::keep_at_exit(&tmp);
            if let Err(e) = moved {
                let _ = std::fs::remove_file(&tmp);
                for (t, _) in iter {
                    let _ = std::fs::remove_file(&t);
                    crate::cancel::keep_at_exit(&t);
                }
                return Err(SceneError::new(ErrorKind::Io, format!("cannot write `{}`: {e}", target.display())));
            }
        }
        self.announced.clear();
        Ok(())
    }

    /// Removes every staged file.
    pub fn abort(&mut self) {
        self.claimed.clear();
        for (tmp, _) in self.staged.drain(..) {
            let _ = std::fs::remove_file(&tmp);
            crate::cancel::keep_at_exit(&tmp);
        }
    }
}

impl Drop for Staging {
    fn drop(&mut self) {
        self.abort();
    }
}
