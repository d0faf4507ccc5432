//! The editor's tuning actions (issue 15): "Tuning" loads the Scala `.scl` scale or `.kbm`
//! keyboard mapping in the path field for the "pitch" key mapping, "12-TET" goes back to the
//! standard tuning. The texts are persisted with the project ([`crate::tuning::TuningState`])
//! and the audio thread's key table is rebuilt at once.

use super::EditorApp;
use crate::tuning::TuningState;
use std::path::Path;

impl EditorApp {
    /// Loads the `.scl` or `.kbm` file in the path field: a scale replaces the tuning (with
    /// the default mapping), a mapping applies to the scale loaded.
    pub(super) fn load_tuning(&mut self) {
        let path = Path::new(self.path.trim()).to_path_buf();
        let name = path.display().to_string();
        let text = match modalforge::limits::read_text(&path, "Scala") {
            Ok(t) => t,
            Err(modalforge::limits::TextReadError::TooLarge(e)) => {
                self.message = Some((e.to_string(), true));
                return;
            }
            Err(modalforge::limits::TextReadError::Io(e)) => {
                self.message = Some((format!("cannot read {name}: {e}"), true));
                return;
            }
        };
        let current = self
            .params
            .tuning
            .read()
            .unwrap_or_else(|e| e.into_inner())
            .clone();
        let is_mapping = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("kbm"));
        let next = if is_mapping {
            let Some(mut state) = current else {
                self.message = Some((
                    format!("{name} is a keyboard mapping: load a .scl scale first"),
                    true,
                ));
                return;
            };
            state.mapping = Some((name.clone(), text));
            state
        } else {
            TuningState {
                scale_file: name.clone(),
                scale: text,
                mapping: None,
            }
        };
        let tuning = match next.tuning() {
            Ok(t) => t,
            Err(e) => {
                self.message = Some((e.to_string(), true));
                return;
            }
        };
        self.set_tuning(Some(next));
        let c4 = tuning
            .frequency_hz(60)
            .map_or("silent".into(), |f| format!("{f:.2} Hz"));
        let a4 = tuning
            .frequency_hz(69)
            .map_or("silent".into(), |f| format!("{f:.2} Hz"));
        let map = if is_mapping {
            "its mapping"
        } else {
            "default mapping"
        };
        self.message = Some((
            format!("tuning: {tuning}, {map} (C4 {c4}, A4 {a4}) from {name}"),
            false,
        ));
    }

    /// Back to 12-tone equal temperament.
    pub(super) fn reset_tuning(&mut self) {
        self.set_tuning(None);
        self.message = Some(("tuning: 12-tone equal temperament, A4 440 Hz".into(), false));
    }

    fn set_tuning(&mut self, state: Option<TuningState>) {
        // Parsed just above (or none): the table cannot refuse it.
        let _ = self.params.key_table.sync(state.as_ref());
        *self
            .params
            .tuning
            .write()
            .unwrap_or_else(|e| e.into_inner()) = state;
    }
}
