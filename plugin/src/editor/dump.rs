//! A text dump of the editor's state, for scripted tests of the real window
//! (`scripts/gui-test.sh`: the standalone app under Xvfb, driven by xdotool).
//!
//! Where it sits: off unless the environment variable [`DUMP_ENV`] names a file. Then, at the
//! end of every frame whose dump differs from the last one written, the window writes
//! `key=value` lines to that file (a temporary file renamed over it, so a reader never sees
//! half a dump): the object (box, voxel count, shape hash, undo depth), the tool, the hit
//! parameters, the message line, the solver's state, the window's size and the screen
//! rectangles of the controls a script clicks (`rect.NAME=x0,y0,x1,y1`, logical pixels from
//! the window's top-left corner). A plugin in a host never sets the variable, so it pays
//! nothing.

use egui::Rect;
use std::path::PathBuf;

/// The environment variable naming the dump file.
pub const DUMP_ENV: &str = "MODALFORGE_EDITOR_DUMP";

/// The dump's destination and what was last written there.
pub(super) struct Dump {
    path: PathBuf,
    last: String,
    /// Controls drawn this frame, by name.
    rects: Vec<(&'static str, Rect)>,
    /// A write failed (said once).
    failed: bool,
}

impl Dump {
    /// The dump [`DUMP_ENV`] asks for, if any.
    pub fn from_env() -> Option<Self> {
        let path = std::env::var_os(DUMP_ENV).filter(|p| !p.is_empty())?;
        Some(Self::to(path.into()))
    }

    /// A dump written to `path`.
    pub fn to(path: PathBuf) -> Self {
        Self {
            path,
            last: String::new(),
            rects: Vec::new(),
            failed: false,
        }
    }

    /// Notes where a control was drawn this frame.
    pub fn mark(&mut self, name: &'static str, rect: Rect) {
        self.rects.retain(|(n, _)| *n != name);
        self.rects.push((name, rect));
    }

    /// The controls drawn since the last write, by name.
    #[cfg(test)]
    pub fn rects(&self) -> &[(&'static str, Rect)] {
        &self.rects
    }

    /// Writes `state` plus this frame's rectangles, if they differ from the last dump; the
    /// rectangles are then cleared for the next frame. A failed write is reported once on
    /// stderr (the window goes on).
    pub fn write(&mut self, state: &[(&str, String)]) {
        let mut text = String::new();
        for (key, value) in state {
            // One line per key: a value's own line breaks would start a bogus key.
            text.push_str(&format!("{key}={}\n", value.replace('\n', " ")));
        }
        self.rects.sort_by_key(|(n, _)| *n);
        for (name, r) in self.rects.drain(..) {
            text.push_str(&format!(
                "rect.{name}={:.0},{:.0},{:.0},{:.0}\n",
                r.min.x, r.min.y, r.max.x, r.max.y
            ));
        }
        if text == self.last {
            return;
        }
        let tmp = self.path.with_extension("tmp");
        let result = std::fs::write(&tmp, &text).and_then(|()| std::fs::rename(&tmp, &self.path));
        match result {
            Err(e) if !self.failed => {
                eprintln!("cannot write the editor dump {}: {e}", self.path.display());
                self.failed = true;
            }
            _ => {}
        }
        self.last = text;
    }
}
