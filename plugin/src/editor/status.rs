//! The window's status line: the solver's state and time, which answer is playing and its
//! expected error, the engine's load; and how often the window redraws by itself to keep it
//! live.
//!
//! Where it sits: methods of [`EditorApp`] that [`super::EditorWindow`] and the layout's
//! bottom panel call each frame; they read the engine's status and live stats (atomics,
//! [`modalforge::engine::EngineControl`]), never waiting on the worker.

use super::EditorApp;
use modalforge::engine::SolveState;
use std::sync::atomic::Ordering;

impl EditorApp {
    /// How soon the window should redraw by itself (input redraws it at once anyway): every
    /// [`LIVE_REDRAW`] while something it shows changes on its own (a solve or a match runs,
    /// notes ring: the status line's timer and counters), else every [`IDLE_REDRAW`]: solves
    /// repaint it through the engine's status watcher, parameter changes through nice-plug,
    /// so the idle redraw only catches a note the host starts. An idle window redrawing 10
    /// times a second cost about a fifth of a core; every 0.5 s, 5.7 % under Xvfb (most of it
    /// Mesa's software rasteriser).
    pub fn redraw_after(&self) -> std::time::Duration {
        let live = self.matching.is_some()
            || self.link.control().is_some_and(|c| {
                matches!(c.status().state, SolveState::Solving { .. })
                    || c.stats().active_modes.load(Ordering::Relaxed) > 0
            });
        if live {
            LIVE_REDRAW
        } else {
            IDLE_REDRAW
        }
    }

    /// The status line: the solver's state and time, the engine's load.
    pub fn status_line(&self) -> (String, bool) {
        let Some(control) = self.link.control() else {
            return (
                "engine not running (the host has not activated the plugin)".into(),
                false,
            );
        };
        let st = control.status();
        let stats = control.stats();
        let engine = format!(
            "{} modes ringing, {} voices, load {:.1}%",
            stats.active_modes.load(Ordering::Relaxed),
            stats.active_voices.load(Ordering::Relaxed),
            100.0 * stats.load()
        );
        // An approximate answer playing while the exact one is solved says so, with its error.
        let playing = match &st.playing {
            Some(p) if p.expected_error.is_some() => format!(
                "playing the {} answer (within ~{}) · ",
                p.solver,
                percent(p.expected_error.unwrap_or(0.0))
            ),
            _ => String::new(),
        };
        match (&st.state, &st.last) {
            (SolveState::Solving { solver, since }, _) => (
                format!(
                    "{playing}solving... {:.1} s ({solver}) · {engine}",
                    since.elapsed().as_secs_f64()
                ),
                false,
            ),
            (SolveState::Idle, Some(last)) if last.error.is_some() => (
                format!(
                    "solve failed: {} (the previous object keeps playing)",
                    last.error.as_deref().unwrap_or("")
                ),
                true,
            ),
            (SolveState::Idle, Some(last)) if last.solver == "recording" => (
                format!(
                    "playing a recording's {} modes (sculpt to play the shape) · {engine}",
                    last.modes
                ),
                false,
            ),
            (SolveState::Idle, Some(last)) => (
                format!(
                    "{playing}{} modes solved in {:.2} s ({}) · {engine}",
                    last.modes,
                    last.ms / 1e3,
                    last.solver
                ),
                false,
            ),
            (SolveState::Idle, None) => (format!("waiting for the first solve · {engine}"), false),
        }
    }
}

/// How often a window with something changing on its own redraws.
const LIVE_REDRAW: std::time::Duration = std::time::Duration::from_millis(100);

/// How often an idle window redraws by itself.
const IDLE_REDRAW: std::time::Duration = std::time::Duration::from_secs(2);

/// A relative error as a short percentage ("0.1 %", "10 %").
fn percent(relative: f64) -> String {
    let p = 100.0 * relative;
    if p < 1.0 {
        format!("{p:.1} %")
    } else {
        format!("{p:.0} %")
    }
}
