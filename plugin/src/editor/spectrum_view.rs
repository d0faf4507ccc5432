//! The editor's spectrum: one vertical line per playable mode at its frequency (log axis,
//! 20 Hz - 20 kHz), as tall as its level relative to the loudest (0 to -80 dB) and coloured by
//! how long it rings (T60); hovering a line names its frequency, decay and level.
//!
//! Where it sits: draws [`modalforge::engine::spectrum::spectrum`] lines, which the editor
//! recomputes when the solved object or the voicing changes.

use egui::{Align2, Color32, FontId, Pos2, Rect, Sense, Stroke, Ui, Vec2};
use modalforge::engine::spectrum::SpectrumLine;

const F_LO: f64 = 20.0;
const F_HI: f64 = 20_000.0;
const DB_RANGE: f64 = 80.0;

/// Horizontal position of `freq_hz` in `rect`.
fn x_of(rect: Rect, freq_hz: f64) -> f32 {
    let t = (freq_hz.clamp(F_LO, F_HI) / F_LO).log10() / (F_HI / F_LO).log10();
    rect.left() + t as f32 * rect.width()
}

/// Colour for a ring time: short rings blue, long ones orange.
fn t60_colour(t60_s: f64) -> Color32 {
    let t = ((t60_s.max(1e-3).log10() + 2.0) / 4.0).clamp(0.0, 1.0) as f32;
    let lerp = |a: f32, b: f32| (a + (b - a) * t) as u8;
    Color32::from_rgb(lerp(70.0, 250.0), lerp(150.0, 170.0), lerp(250.0, 60.0))
}

/// Draws the spectrum in a strip `height` pixels tall across the available width.
pub fn show(ui: &mut Ui, lines: &[SpectrumLine], height: f32) {
    let (response, painter) =
        ui.allocate_painter(Vec2::new(ui.available_width(), height), Sense::hover());
    let rect = response.rect;
    painter.rect_filled(rect, 2.0, Color32::from_gray(18));
    let grid = Color32::from_gray(55);
    let label = Color32::from_gray(150);
    for f in [50.0, 100.0, 200.0, 500.0, 1e3, 2e3, 5e3, 1e4] {
        let x = x_of(rect, f);
        painter.line_segment(
            [Pos2::new(x, rect.top()), Pos2::new(x, rect.bottom())],
            Stroke::new(1.0, grid),
        );
        let text = if f >= 1e3 {
            format!("{}k", f / 1e3)
        } else {
            format!("{f}")
        };
        painter.text(
            Pos2::new(x + 2.0, rect.bottom() - 2.0),
            Align2::LEFT_BOTTOM,
            text,
            FontId::proportional(10.0),
            label,
        );
    }
    let loudest = lines.iter().map(|l| l.amplitude).fold(0.0, f64::max);
    if loudest <= 0.0 {
        painter.text(
            rect.center(),
            Align2::CENTER_CENTER,
            "no modes yet",
            FontId::proportional(12.0),
            label,
        );
        return;
    }
    let y_of = |amplitude: f64| {
        let db = 20.0 * (amplitude / loudest).max(1e-12).log10();
        let t = (1.0 + db / DB_RANGE).clamp(0.0, 1.0) as f32;
        rect.bottom() - t * (rect.height() - 14.0)
    };
    for l in lines {
        let x = x_of(rect, l.freq_hz);
        painter.line_segment(
            [Pos2::new(x, rect.bottom()), Pos2::new(x, y_of(l.amplitude))],
            Stroke::new(2.0, t60_colour(l.t60_s())),
        );
    }
    painter.text(
        rect.left_top() + Vec2::new(4.0, 2.0),
        Align2::LEFT_TOP,
        format!(
            "{} modes · 0 to -{DB_RANGE} dB · colour: ring time",
            lines.len()
        ),
        FontId::proportional(10.0),
        label,
    );
    if let Some(p) = response.hover_pos() {
        let nearest = lines
            .iter()
            .map(|l| ((x_of(rect, l.freq_hz) - p.x).abs(), l))
            .filter(|(d, _)| *d < 5.0)
            .min_by(|a, b| a.0.total_cmp(&b.0));
        if let Some((_, l)) = nearest {
            let db = 20.0 * (l.amplitude / loudest).log10();
            response.on_hover_text_at_pointer(format!(
                "mode {}: {:.1} Hz, decay {:.2} /s (T60 {:.2} s), {:.1} dB",
                l.index + 1,
                l.freq_hz,
                l.decay_per_s,
                l.t60_s(),
                db
            ));
        }
    }
}
