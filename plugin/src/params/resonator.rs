//! The "Resonator" parameter group: the side-chain input played through the object
//! ([`modalforge::engine::resonator`]).

use super::{float, skewed};
use modalforge::engine::resonator::ResonatorSettings;
use nice_plug::prelude::*;

/// Input gains at or below this (dB) switch the effect off.
pub const OFF_DB: f32 = -60.0;

/// What a held key does.
#[derive(Enum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum HeldNote {
    /// A key strikes the object once (note-off mutes it if Note-off Mute is on).
    #[id = "strike"]
    #[name = "Strike"]
    Strike,
    /// A key scrapes the object while held: noise through its modes, louder with velocity,
    /// louder and brighter with pressure, until note-off.
    #[id = "scrape"]
    #[name = "Scrape"]
    Scrape,
}

/// The "Resonator" group: frozen ids `rin`, `rmix`, `rlow`, `rhigh`, `held`.
#[derive(Params)]
pub struct ResonatorGroup {
    /// Gain on the side-chain input before the object, dB (at the bottom: off).
    #[id = "rin"]
    pub input_gain_db: FloatParam,
    /// Share of the resonated input in what is added to the output (the rest: the filtered
    /// input itself).
    #[id = "rmix"]
    pub mix: FloatParam,
    /// Low cut on the input, Hz.
    #[id = "rlow"]
    pub low_cut_hz: FloatParam,
    /// High cut on the input, Hz.
    #[id = "rhigh"]
    pub high_cut_hz: FloatParam,
    /// Whether a key strikes or scrapes the object.
    #[id = "held"]
    pub held: EnumParam<HeldNote>,
}

impl Default for ResonatorGroup {
    fn default() -> Self {
        Self {
            input_gain_db: float(
                "Resonator Input",
                0.0,
                FloatRange::Linear {
                    min: OFF_DB,
                    max: 24.0,
                },
                " dB",
                1,
            ),
            mix: float(
                "Resonator Mix",
                1.0,
                FloatRange::Linear { min: 0.0, max: 1.0 },
                "",
                2,
            ),
            low_cut_hz: float("Resonator Low Cut", 20.0, skewed(10.0, 2000.0), " Hz", 0),
            high_cut_hz: float(
                "Resonator High Cut",
                20_000.0,
                skewed(500.0, 22_000.0),
                " Hz",
                0,
            ),
            held: EnumParam::new("Held Notes", HeldNote::Strike),
        }
    }
}

impl ResonatorGroup {
    /// The engine's settings for the current values (smoothing is the filters' own).
    pub fn settings(&self) -> ResonatorSettings {
        let db = self.input_gain_db.value();
        ResonatorSettings {
            input_gain: if db <= OFF_DB {
                0.0
            } else {
                10f32.powf(db / 20.0)
            },
            mix: self.mix.value(),
            low_cut_hz: self.low_cut_hz.value() as f64,
            high_cut_hz: self.high_cut_hz.value() as f64,
        }
    }
}
