//! Microtuning: Scala scales (`.scl`) and keyboard mappings (`.kbm`), the de facto standard
//! formats of tuning files (Manuel Op de Coul's Scala; <https://www.huygens-fokker.org/scala/>,
//! "scl_format.html" and "help.htm#mappings").
//!
//! Where it sits: the plugin's "pitch" key mapping asks a [`Tuning`] for each key's frequency
//! (a table of 128 computed off the audio thread, [`Tuning::table`]); the engine then scales the
//! object so its pitch ([`crate::engine::pitch`]) sounds at it.
//!
//! - `.scl`: `!` starts a comment line; the first other line is a description, the next the
//!   number of notes `n`, then `n` pitches, one a line: a number with a `.` is cents, otherwise a
//!   ratio `p/q` or an integer `p` (`p/1`). Degree 0 is the implicit `1/1`; the last pitch is the
//!   period (usually `2/1`). Text after the number is ignored.
//! - `.kbm`: seven numbers (map size, first and last MIDI note to retune, the middle note where
//!   degree 0 sits, the reference note, its frequency in Hz, the scale degree of the formal
//!   octave), then `map size` entries: a scale degree, or `x` for a key that stays silent. Map
//!   size 0 maps keys linearly, one degree a key. Without a `.kbm` ([`Mapping::default`]):
//!   linear, degree 0 on middle C (key 60) at its 12-TET frequency, 261.63 Hz.
//!
//! Key `k` with `d = k - middle` falls `floor(d / m)` formal octaves and `d mod m` map entries
//! from the middle note (`m` the map size); its pitch in cents above the middle note is the
//! mapped degree's plus that many octaves, and the whole keyboard is scaled so the reference
//! note sounds at its frequency.

use std::fmt;

/// Most notes a scale may have (Scala's own files stay far below).
pub const MAX_NOTES: usize = 4096;

/// Most entries a keyboard map may have.
pub const MAX_MAP: usize = 4096;

/// MIDI keys.
pub const KEYS: usize = 128;

/// Why a tuning file cannot be used; says which line and how to fix it.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TuningError {
    /// A Scala scale file that does not parse.
    #[error("{file}: {what}; a Scala .scl file has a description line, a note count and that many pitches (cents with a '.', or ratios like 3/2)")]
    Scale {
        /// The file.
        file: String,
        /// What is wrong, with its line.
        what: String,
    },
    /// A keyboard mapping file that does not parse.
    #[error("{file}: {what}; a .kbm file has 7 numbers (map size, first, last, middle and reference note, reference Hz, octave degree) then the map")]
    Mapping {
        /// The file.
        file: String,
        /// What is wrong, with its line.
        what: String,
    },
}

/// A Scala scale: the pitches of degrees `1..=n` in cents above degree 0 (the last is the
/// period).
#[derive(Clone, Debug, PartialEq)]
pub struct Scale {
    /// The file's description line.
    pub description: String,
    /// Cents of degrees 1..=n.
    pub cents: Vec<f64>,
}

impl Scale {
    /// Parses `.scl` text; `file` names it in errors.
    pub fn parse(text: &str, file: &str) -> Result<Self, TuningError> {
        let err = |line: usize, what: String| TuningError::Scale {
            file: file.into(),
            what: format!("line {line}: {what}"),
        };
        let mut lines = text
            .lines()
            .enumerate()
            .map(|(i, l)| (i + 1, l.trim_end_matches('\r')))
            .filter(|(_, l)| !l.starts_with('!'));
        let description = lines
            .next()
            .map(|(_, l)| l.trim().to_string())
            .ok_or_else(|| err(1, "the file is empty".into()))?;
        let (at, count) = lines.next().ok_or_else(|| err(2, "no note count".into()))?;
        let count: usize = first_word(count).parse().map_err(|_| {
            err(
                at,
                format!("note count {:?} is not a whole number", count.trim()),
            )
        })?;
        if count > MAX_NOTES {
            return Err(err(at, format!("{count} notes; at most {MAX_NOTES}")));
        }
        let mut cents = Vec::with_capacity(count);
        let mut last_at = at;
        for (at, line) in lines.by_ref() {
            if cents.len() == count {
                break;
            }
            let word = first_word(line);
            if word.is_empty() {
                continue;
            }
            let c = pitch_cents(word).ok_or_else(|| {
                err(
                    at,
                    format!("{word:?} is not cents (with a '.') or a positive ratio"),
                )
            })?;
            cents.push(c);
            last_at = at;
        }
        if cents.len() < count {
            return Err(err(
                text.lines().count(),
                format!("{count} notes announced, {} found", cents.len()),
            ));
        }
        if count == 0 {
            // Only the implicit 1/1: a scale of octaves.
            cents.push(1200.0);
        }
        let period = *cents.last().expect("at least one pitch");
        if period <= 0.0 {
            return Err(err(
                last_at,
                format!("the period (last pitch, {period} cents) must be above 1/1"),
            ));
        }
        Ok(Self { description, cents })
    }

    /// Notes per period.
    pub fn len(&self) -> usize {
        self.cents.len()
    }

    /// Always false: a scale has its period at least.
    pub fn is_empty(&self) -> bool {
        self.cents.is_empty()
    }

    /// Cents of degree `d` (any integer: other periods included) above degree 0.
    pub fn degree_cents(&self, d: i64) -> f64 {
        let n = self.cents.len() as i64;
        let (periods, r) = (d.div_euclid(n), d.rem_euclid(n));
        let within = if r == 0 {
            0.0
        } else {
            self.cents[r as usize - 1]
        };
        periods as f64 * self.period_cents() + within
    }

    /// The period, cents.
    pub fn period_cents(&self) -> f64 {
        *self.cents.last().expect("a scale has a period")
    }

    /// The `n`-tone equal division of the octave.
    pub fn equal(n: usize) -> Self {
        let n = n.max(1);
        Self {
            description: format!("{n}-tone equal temperament"),
            cents: (1..=n).map(|i| 1200.0 * i as f64 / n as f64).collect(),
        }
    }
}

/// A keyboard mapping (`.kbm`).
#[derive(Clone, Debug, PartialEq)]
pub struct Mapping {
    /// Keys retuned: `first..=last`; the others are silent.
    pub first: u8,
    /// See `first`.
    pub last: u8,
    /// The key where degree 0 sits.
    pub middle: i64,
    /// The key tuned to `reference_hz`.
    pub reference: i64,
    /// Its frequency, Hz.
    pub reference_hz: f64,
    /// The scale degree of the formal octave (0: the scale's own period).
    pub octave_degree: i64,
    /// Degree of each key within a map repeat (`None`: silent); empty maps linearly.
    pub map: Vec<Option<i64>>,
}

impl Default for Mapping {
    /// Linear, degree 0 on middle C at its 12-TET frequency.
    fn default() -> Self {
        Self {
            first: 0,
            last: 127,
            middle: 60,
            reference: 60,
            reference_hz: 440.0 * 2f64.powf(-9.0 / 12.0),
            octave_degree: 0,
            map: Vec::new(),
        }
    }
}

impl Mapping {
    /// Parses `.kbm` text; `file` names it in errors.
    pub fn parse(text: &str, file: &str) -> Result<Self, TuningError> {
        let err = |line: usize, what: String| TuningError::Mapping {
            file: file.into(),
            what: format!("line {line}: {what}"),
        };
        let mut words = text
            .lines()
            .enumerate()
            .map(|(i, l)| (i + 1, first_word(l.trim_end_matches('\r'))))
            .filter(|(_, w)| !w.is_empty() && !w.starts_with('!'));
        let mut number = |what: &str| -> Result<(usize, f64), TuningError> {
            let (at, w) = words
                .next()
                .ok_or_else(|| err(0, format!("the file ends before the {what}")))?;
            let v: f64 = w
                .parse()
                .map_err(|_| err(at, format!("the {what} {w:?} is not a number")))?;
            if !v.is_finite() {
                return Err(err(at, format!("the {what} is not finite")));
            }
            Ok((at, v))
        };
        let key = |(at, v): (usize, f64), what: &str| -> Result<i64, TuningError> {
            if v.fract() != 0.0 || !(0.0..=127.0).contains(&v) {
                return Err(err(at, format!("the {what} {v} is not a MIDI key (0-127)")));
            }
            Ok(v as i64)
        };
        let (at, size) = number("map size")?;
        if size.fract() != 0.0 || size < 0.0 || size > MAX_MAP as f64 {
            return Err(err(at, format!("map size {size}: give 0 to {MAX_MAP}")));
        }
        let first = key(number("first note")?, "first note")?;
        let last = key(number("last note")?, "last note")?;
        let middle = key(number("middle note")?, "middle note")?;
        let reference = key(number("reference note")?, "reference note")?;
        let (at, reference_hz) = number("reference frequency")?;
        if reference_hz <= 0.0 {
            return Err(err(
                at,
                format!("reference frequency {reference_hz} Hz must be positive"),
            ));
        }
        let (at, octave) = number("octave degree")?;
        if octave.fract() != 0.0 || octave < 0.0 {
            return Err(err(
                at,
                format!("octave degree {octave} must be a whole number >= 0"),
            ));
        }
        let mut map = Vec::with_capacity(size as usize);
        for _ in 0..size as usize {
            // A map shorter than its size leaves the rest silent (Scala's reading).
            let Some((at, w)) = words.next() else {
                map.push(None);
                continue;
            };
            if w.eq_ignore_ascii_case("x") {
                map.push(None);
            } else {
                let d: i64 = w
                    .parse()
                    .map_err(|_| err(at, format!("map entry {w:?} is not a degree or 'x'")))?;
                map.push(Some(d));
            }
        }
        Ok(Self {
            first: first as u8,
            last: last as u8,
            middle,
            reference,
            reference_hz,
            octave_degree: octave as i64,
            map,
        })
    }
}

/// A scale on a keyboard.
#[derive(Clone, Debug, PartialEq)]
pub struct Tuning {
    /// The scale.
    pub scale: Scale,
    /// Its mapping.
    pub mapping: Mapping,
}

impl Tuning {
    /// Cents of key `k` above the middle note, or `None` where it is silent.
    fn cents_of(&self, k: i64) -> Option<f64> {
        let m = &self.mapping;
        if m.map.is_empty() {
            return Some(self.scale.degree_cents(k - m.middle));
        }
        let size = m.map.len() as i64;
        let d = k - m.middle;
        let (octaves, i) = (d.div_euclid(size), d.rem_euclid(size));
        let degree = m.map[i as usize]?;
        let octave = if m.octave_degree == 0 {
            self.scale.period_cents()
        } else {
            self.scale.degree_cents(m.octave_degree)
        };
        Some(octaves as f64 * octave + self.scale.degree_cents(degree))
    }

    /// Frequency of MIDI key `key`, Hz; `None` where the mapping leaves it silent.
    pub fn frequency_hz(&self, key: u8) -> Option<f64> {
        let m = &self.mapping;
        if key < m.first || key > m.last {
            return None;
        }
        let c = self.cents_of(key as i64)?;
        // The reference key sounds at its frequency; a silent reference key is taken where
        // the map's linear continuation would put it (degree = distance from the middle).
        let r = self
            .cents_of(m.reference)
            .unwrap_or_else(|| self.scale.degree_cents(m.reference - m.middle));
        let f = m.reference_hz * 2f64.powf((c - r) / 1200.0);
        (f.is_finite() && f > 0.0).then_some(f)
    }

    /// Every key's frequency (0 for a silent key), for the audio thread's table.
    pub fn table(&self) -> [f64; KEYS] {
        std::array::from_fn(|k| self.frequency_hz(k as u8).unwrap_or(0.0))
    }
}

impl fmt::Display for Tuning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let d = if self.scale.description.is_empty() {
            "scale"
        } else {
            &self.scale.description
        };
        write!(f, "{d} ({} notes a period)", self.scale.len())
    }
}

/// The first whitespace-separated word of a line ("" for a blank one).
fn first_word(line: &str) -> &str {
    line.split_whitespace().next().unwrap_or("")
}

/// Cents of a Scala pitch word: cents with a `.`, else a positive ratio `p/q` or `p`.
fn pitch_cents(word: &str) -> Option<f64> {
    let c = if word.contains('.') {
        word.parse::<f64>().ok()?
    } else {
        let (p, q) = word.split_once('/').unwrap_or((word, "1"));
        let (p, q): (u64, u64) = (p.parse().ok()?, q.parse().ok()?);
        if p == 0 || q == 0 {
            return None;
        }
        1200.0 * (p as f64 / q as f64).log2()
    };
    c.is_finite().then_some(c)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Cents between two frequencies.
    fn cents(a: f64, b: f64) -> f64 {
        1200.0 * (a / b).log2()
    }

    const TET19: &str = "! 19edo.scl\n!\n19 equal divisions of the octave\n 19\n!\n\
        63.15789\n126.31579\n189.47368\n252.63158\n315.78947\n378.94737\n442.10526\n\
        505.26316\n568.42105\n631.57895\n694.73684\n757.89474\n821.05263\n884.21053\n\
        947.36842\n1010.52632\n1073.68421\n1136.84211\n2/1\n";

    /// Truth: 19-TET from its definition, `f(k) = 261.6256 * 2^((k - 60) / 19)` with the
    /// default mapping. The file's cents have 5 decimals (1e-5 cent), so every key is within
    /// 1e-4 cent, far inside the 0.1 cent.
    #[test]
    fn nineteen_tone_equal_temperament_is_in_tune_on_every_key() {
        let scale = Scale::parse(TET19, "19edo.scl").unwrap();
        assert_eq!(scale.len(), 19);
        assert_eq!(scale.description, "19 equal divisions of the octave");
        let t = Tuning {
            scale,
            mapping: Mapping::default(),
        };
        let c4 = 440.0 * 2f64.powf(-9.0 / 12.0);
        for k in 0..128u8 {
            let want = c4 * 2f64.powf((k as f64 - 60.0) / 19.0);
            let got = t.frequency_hz(k).unwrap();
            assert!(cents(got, want).abs() < 1e-4, "key {k}: {got} vs {want}");
        }
        // The same from the generator.
        let eq = Tuning {
            scale: Scale::equal(19),
            mapping: Mapping::default(),
        };
        assert!(cents(eq.frequency_hz(79).unwrap(), 2.0 * c4).abs() < 1e-9);
    }

    /// Truth: just intonation by hand. A 7-note just major scale (ratios) mapped on the white
    /// keys of a 12-key map with `x` on the black ones, middle C 60, A4 (69) at 440 Hz: A4 is
    /// 5/3 above C, so C sits at 264 Hz; E4 = 5/4 x 264 = 330 Hz; C5 = 528 Hz; C#4 is silent;
    /// A3 = 220 Hz; keys outside first..=last are silent.
    #[test]
    fn a_keyboard_map_places_degrees_silences_keys_and_sets_the_reference() {
        let scl = "! just.scl\nJust major\n7\n9/8\n5/4\n4/3\n3/2\n5/3\n15/8\n2/1\n";
        let kbm = "! white keys\n12\n0\n127\n60\n69\n440.0\n7\n\
                   0\nx\n1\nx\n2\n3\nx\n4\nx\n5\nx\n6\n";
        let t = Tuning {
            scale: Scale::parse(scl, "just.scl").unwrap(),
            mapping: Mapping::parse(kbm, "white.kbm").unwrap(),
        };
        let close = |k: u8, hz: f64| {
            let got = t.frequency_hz(k).unwrap();
            assert!(cents(got, hz).abs() < 1e-9, "key {k}: {got} vs {hz}");
        };
        close(69, 440.0);
        close(60, 264.0);
        close(64, 330.0);
        close(72, 528.0);
        close(57, 220.0);
        assert_eq!(t.frequency_hz(61), None);
        let narrow = Mapping {
            first: 48,
            last: 84,
            ..t.mapping.clone()
        };
        let t2 = Tuning {
            mapping: narrow,
            ..t.clone()
        };
        assert_eq!(t2.frequency_hz(47), None);
        assert!(t2.frequency_hz(48).is_some());
    }

    #[test]
    fn bad_files_give_one_line_errors_that_name_the_line() {
        let bad_scales = [
            ("", "empty"),
            ("desc\n", "no note count"),
            ("desc\nthree\n", "not a whole number"),
            ("desc\n3\n100.0\n", "3 notes announced, 1 found"),
            ("desc\n2\n100.0\n0/5\n", "not cents"),
            ("desc\n1\n-1200.0\n", "period"),
            ("desc\n99999999\n", "at most"),
        ];
        for (text, want) in bad_scales {
            let e = Scale::parse(text, "s.scl").unwrap_err().to_string();
            assert!(e.contains(want) && !e.contains('\n'), "{text:?}: {e}");
        }
        let bad_maps = [
            (
                "12\n0\n127\n60\n69\n",
                "ends before the reference frequency",
            ),
            ("12\n0\n200\n60\n69\n440\n12\n", "not a MIDI key"),
            ("12\n0\n127\n60\n69\n-440\n12\n", "must be positive"),
            ("12\n0\n127\n60\n69\nNaN\n12\n", "not finite"),
            ("2\n0\n127\n60\n69\n440\n12\n0\nq\n", "not a degree"),
        ];
        for (text, want) in bad_maps {
            let e = Mapping::parse(text, "m.kbm").unwrap_err().to_string();
            assert!(e.contains(want) && !e.contains('\n'), "{text:?}: {e}");
        }
    }
}
