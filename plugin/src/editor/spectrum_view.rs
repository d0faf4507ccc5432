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
/// Height of the frequency labels' strip along the bottom, pixels (mode lines stop above it).
const AXIS_PX: f32 = 12.0;
/// Height of the title band along the top, pixels (mode lines stop below it).
const TITLE_PX: f32 = 14.0;

/// The strip's plot area: what is left between the title band and the axis labels' strip.
fn plot_area(rect: Rect) -> Rect {
    let bottom = (rect.bottom() - AXIS_PX).max(rect.top());
    Rect::from_min_max(
        Pos2::new(rect.left(), (rect.top() + TITLE_PX).min(bottom)),
        Pos2::new(rect.right(), bottom),
    )
}

/// A mode line's ends in `rect`: at its frequency, from the plot area's floor up to its level
/// relative to `loudest` (0 dB at the top, -[`DB_RANGE`] at the floor).
fn mode_line(rect: Rect, freq_hz: f64, amplitude: f64, loudest: f64) -> [Pos2; 2] {
    let plot = plot_area(rect);
    let db = 20.0 * (amplitude / loudest).max(1e-12).log10();
    let t = (1.0 + db / DB_RANGE).clamp(0.0, 1.0) as f32;
    let x = x_of(rect, freq_hz);
    [
        Pos2::new(x, plot.bottom()),
        Pos2::new(x, plot.bottom() - t * plot.height()),
    ]
}

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
    let plot = plot_area(rect);
    for f in [50.0, 100.0, 200.0, 500.0, 1e3, 2e3, 5e3, 1e4] {
        let x = x_of(rect, f);
        painter.line_segment(
            [Pos2::new(x, rect.top()), Pos2::new(x, plot.bottom())],
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
    for l in lines {
        painter.line_segment(
            mode_line(rect, l.freq_hz, l.amplitude, loudest),
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mode_lines_leave_the_axis_labels_and_the_title_clear() {
        // Every line, from the loudest to one far below the range, at any frequency (in range
        // or clamped to it), stays between the title band and the labels' strip; the loudest
        // reaches the top of that area and a -40 dB mode half way (the dB axis is linear).
        let rect = Rect::from_min_max(Pos2::new(0.0, 100.0), Pos2::new(600.0, 190.0));
        let plot = plot_area(rect);
        assert_eq!(plot.bottom(), rect.bottom() - AXIS_PX);
        assert_eq!(plot.top(), rect.top() + TITLE_PX);
        for f in [5.0, 20.0, 440.0, 19_999.0, 50_000.0] {
            for a in [1.0, 0.3, 1e-2, 1e-6, 0.0] {
                let [low, high] = mode_line(rect, f, a, 1.0);
                assert!(low.y <= plot.bottom() && high.y >= plot.top() && high.y <= low.y);
                assert!((rect.left()..=rect.right()).contains(&low.x));
            }
        }
        assert_eq!(mode_line(rect, 1e3, 1.0, 1.0)[1].y, plot.top());
        let half = mode_line(rect, 1e3, 1e-2, 1.0)[1].y;
        assert!((half - (plot.top() + plot.bottom()) / 2.0).abs() < 1e-3);
    }
}
