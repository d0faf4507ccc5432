//! The editor's recording actions (issue 14): "Match recording" fits the sculpted object's
//! material and damping to a WAV, "Play recording" plays the WAV's own modes instead of the
//! shape. The work runs on a thread ([`super::matching`]); these methods start it, poll it
//! every frame and apply what it found through the host.

use super::matching;
use super::EditorApp;
use crate::materials::MaterialChoice;
use modalforge::engine::recorded::RecordedObject;
use modalforge::engine::DampingParams;
use nice_plug::prelude::*;
use std::path::Path;

impl EditorApp {
    /// Starts "Match recording" on the file in the path field: the sculpted object as solved
    /// (cropped, at the Size parameter), struck at the Hit parameters, from the current
    /// material's E/rho.
    pub(super) fn start_match(&mut self) {
        let path = Path::new(self.path.trim()).to_path_buf();
        let grid = match self.sculptor.sculpt().and_then(|s| s.to_grid()) {
            Ok(g) => g,
            Err(e) => {
                self.message = Some((e.to_string(), true));
                return;
            }
        };
        let longest = grid.dims().into_iter().max().unwrap_or(1) as f64;
        let h = self.params.material.size_m.value() as f64 / longest;
        let grid = match grid.with_voxel_size(h) {
            Ok(g) => g,
            Err(e) => {
                self.message = Some((e.to_string(), true));
                return;
            }
        };
        let voicing = self.params.voicing(&self.table, 1.0, 1.0);
        let mut hit = voicing.hit.reference_hit(grid.dims());
        hit.point_m = hit.point_m.map(|c| c * h);
        let e_over_rho = voicing.youngs_modulus_pa / voicing.density_kg_m3;
        let m = matching::Matching::start(path, grid, hit, e_over_rho);
        self.message = Some((format!("analysing {}...", m.file), false));
        self.matching = Some(m);
    }

    /// Polls a running match: shows its progress, and when it is done sets the material and
    /// damping parameters from it (through the host) and says what it found.
    pub(super) fn poll_match(&mut self, setter: &ParamSetter) {
        let Some(m) = &self.matching else {
            return;
        };
        let Some(result) = m.poll() else {
            self.message = Some((
                format!("analysing {}... {:.0} s", m.file, m.elapsed_s()),
                false,
            ));
            return;
        };
        self.matching = None;
        match result {
            Ok(matching::Outcome::Fitted(matched)) => self.apply_fitted(matched, setter),
            Ok(matching::Outcome::Played(played)) => self.apply_played(played, setter),
            Err(e) => self.message = Some((e.to_string(), true)),
        }
    }

    /// "Match recording" done: the material and damping parameters from the fit.
    fn apply_fitted(&mut self, matched: matching::Matched, setter: &ParamSetter) {
        let Some(knobs) = matching::Knobs::of(&matched.material) else {
            self.message = Some((
                format!("{}: its damping law is not a knob setting", matched.summary),
                true,
            ));
            return;
        };
        let p = &self.params;
        setter.begin_set_parameter(&p.material.preset);
        setter.set_parameter(&p.material.preset, MaterialChoice::Custom);
        setter.end_set_parameter(&p.material.preset);
        set_float(setter, &p.material.youngs_gpa, knobs.youngs_gpa);
        set_float(setter, &p.material.density, knobs.density);
        set_float(setter, &p.material.poisson, knobs.poisson);
        self.set_damping_knobs(knobs.damping, setter);
        let saved = matched
            .saved
            .map_or(String::new(), |f| format!("; saved {}", f.display()));
        self.message = Some((format!("{}{saved}", matched.summary), false));
    }

    /// "Play recording" done: the damping knobs from the recording's law, and its modes, made
    /// under the knobs then in force ([`RecordedObject`]), played instead of the shape.
    fn apply_played(&mut self, played: matching::Played, setter: &ParamSetter) {
        let mut voicing = self.params.voicing(&self.table, 1.0, 1.0);
        if let Some(knobs) = played.damping {
            self.set_damping_knobs(knobs, setter);
            // The knobs' law, as the voicing will read it once the host has applied them.
            let (law, a, b) = knobs;
            voicing.damping = match law {
                crate::params::DampingChoice::PowerLaw => DampingParams::PowerLaw {
                    mu1: a as f64,
                    mu2: b as f64,
                },
                _ => DampingParams::Rayleigh {
                    alpha1: a as f64,
                    alpha2: b as f64 * 1e-6,
                },
            };
        }
        match RecordedObject::new(played.name, &played.modes, &voicing) {
            Ok(object) => {
                *self
                    .params
                    .recording
                    .write()
                    .unwrap_or_else(|e| e.into_inner()) = Some(object);
                self.message = Some((played.summary, false));
            }
            Err(e) => self.message = Some((e.to_string(), true)),
        }
    }

    /// Sets the damping law and its two knobs through the host.
    fn set_damping_knobs(
        &self,
        (law, a, b): (crate::params::DampingChoice, f32, f32),
        setter: &ParamSetter,
    ) {
        let p = &self.params;
        setter.begin_set_parameter(&p.damping.law);
        setter.set_parameter(&p.damping.law, law);
        setter.end_set_parameter(&p.damping.law);
        match law {
            crate::params::DampingChoice::PowerLaw => {
                set_float(setter, &p.damping.mu1, a);
                set_float(setter, &p.damping.mu2, b);
            }
            _ => {
                set_float(setter, &p.damping.alpha1, a);
                set_float(setter, &p.damping.alpha2_us, b);
            }
        }
    }

    /// Starts "Play recording" on the file in the path field.
    pub(super) fn start_play(&mut self) {
        let path = Path::new(self.path.trim()).to_path_buf();
        let m = matching::Matching::start_play(path);
        self.message = Some((format!("analysing {}...", m.file), false));
        self.matching = Some(m);
    }
}

/// Sets one float parameter through the host (a complete gesture).
fn set_float(setter: &ParamSetter, param: &FloatParam, value: f32) {
    setter.begin_set_parameter(param);
    setter.set_parameter(param, value);
    setter.end_set_parameter(param);
}
