//! Object + material presets: `presets/objects/*.toml` (compiled in) and the user's own, saved
//! and loaded by the editor.
//!
//! Where it sits: the editor applies a preset by setting parameters (through the host, so it is
//! undoable and automatable there) and replacing the sculpted object; tests solve every
//! built-in one and check it sounds like its name.
//!
//! Format (TOML):
//! ```toml
//! name = "Glass bowl"
//! description = "..."
//! shape = "bowl:d=16,wall=2"        # a built-in shape (CLI --shape syntax), or
//! # object = { dims = [16, 16, 8], voxels = "hex..." }   # sculpted voxels, x fastest
//! material = "glass"                # a material id (presets/materials), or "custom" with
//! # youngs_gpa = 70.0, density_kg_m3 = 2500.0, poisson = 0.25
//! size_m = 0.2
//! hardness_ms = 0.3
//! hit = [0.37, 0.41, 1.0]
//! ```

use crate::error::PluginError;
use crate::materials::MaterialChoice;
use crate::sculpt::Sculpt;
use modalforge::engine::Voicing;
use modalforge::material::Material;
use nice_plug::prelude::Enum;
use serde::{Deserialize, Serialize};

/// The built-in presets' files.
const BUILTIN: &[(&str, &str)] = &[
    (
        "glass-bowl",
        include_str!("../../presets/objects/glass-bowl.toml"),
    ),
    (
        "steel-bar",
        include_str!("../../presets/objects/steel-bar.toml"),
    ),
    (
        "wooden-block",
        include_str!("../../presets/objects/wooden-block.toml"),
    ),
    (
        "ceramic-cup",
        include_str!("../../presets/objects/ceramic-cup.toml"),
    ),
    ("bell", include_str!("../../presets/objects/bell.toml")),
    (
        "aluminium-plate",
        include_str!("../../presets/objects/aluminium-plate.toml"),
    ),
    (
        "tin-can",
        include_str!("../../presets/objects/tin-can.toml"),
    ),
    (
        "iron-pipe",
        include_str!("../../presets/objects/iron-pipe.toml"),
    ),
    (
        "plastic-crate",
        include_str!("../../presets/objects/plastic-crate.toml"),
    ),
    (
        "brass-gong",
        include_str!("../../presets/objects/brass-gong.toml"),
    ),
    (
        "wooden-slat",
        include_str!("../../presets/objects/wooden-slat.toml"),
    ),
    (
        "glass-vase",
        include_str!("../../presets/objects/glass-vase.toml"),
    ),
];

/// Sculpted voxels in a preset file: dimensions and the packed bits as hex.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StoredObject {
    /// Voxels along x, y, z.
    pub dims: [usize; 3],
    /// [`Sculpt::bits`] as lowercase hex.
    pub voxels: String,
    /// [`Sculpt::fill`] (the partial voxels) as lowercase hex; absent for a binary object.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub fill: String,
}

/// One object + material preset.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Preset {
    /// Display name.
    pub name: String,
    /// One line about how it sounds.
    #[serde(default)]
    pub description: String,
    /// A built-in shape spec (exclusive with `object`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shape: Option<String>,
    /// Sculpted voxels (exclusive with `shape`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub object: Option<StoredObject>,
    /// Material id (`glass`, `steel`, ..., or `custom`).
    pub material: String,
    /// Custom material: Young's modulus, GPa.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub youngs_gpa: Option<f32>,
    /// Custom material: density, kg/m^3.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub density_kg_m3: Option<f32>,
    /// Custom material: Poisson's ratio.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub poisson: Option<f32>,
    /// The object's longest side, m.
    pub size_m: f32,
    /// Mallet contact time, ms.
    pub hardness_ms: f32,
    /// Hit point as fractions of the object's extent.
    pub hit: [f32; 3],
}

impl Preset {
    /// Every built-in preset (parsed from the compiled-in files).
    pub fn builtin() -> Vec<Preset> {
        BUILTIN
            .iter()
            .map(|(file, text)| {
                // The compiled-in objects are rasterised when chosen, not here: checking all
                // of them rasterised every preset shape (~0.35 s) each time a host created
                // the plugin, since hosts build the editor's state at load. The presets test
                // rasterises and solves each one.
                Self::parse(text, &format!("presets/objects/{file}.toml"), false)
                    .unwrap_or_else(|e| panic!("a compiled-in preset is valid: {e}"))
            })
            .collect()
    }

    /// Parses and checks a preset file; `origin` names it in errors.
    pub fn from_toml(text: &str, origin: &str) -> Result<Preset, PluginError> {
        Self::parse(text, origin, true)
    }

    /// [`Preset::from_toml`], its object decoded (and a shape spec rasterised) only when
    /// `check_object`.
    fn parse(text: &str, origin: &str, check_object: bool) -> Result<Preset, PluginError> {
        let in_preset = |e: PluginError| PluginError::InPreset {
            origin: origin.into(),
            source: Box::new(e),
        };
        let p: Preset = toml::from_str(text)
            .map_err(|e| in_preset(PluginError::NotAPreset(e.message().into())))?;
        p.check_fields().map_err(in_preset)?;
        if check_object {
            p.sculpt().map_err(in_preset)?;
        }
        Ok(p)
    }

    /// The preset as a file.
    pub fn to_toml(&self) -> String {
        toml::to_string(self).unwrap_or_default()
    }

    /// The material choice.
    pub fn material_choice(&self) -> Option<MaterialChoice> {
        let ids = MaterialChoice::ids()?;
        let i = ids.iter().position(|id| *id == self.material)?;
        Some(MaterialChoice::from_index(i))
    }

    /// The object.
    pub fn sculpt(&self) -> Result<Sculpt, PluginError> {
        match (&self.shape, &self.object) {
            (Some(spec), None) => Sculpt::from_spec(spec),
            (None, Some(o)) => {
                let bits = decode_hex(&o.voxels).ok_or(PluginError::NotHex("voxels"))?;
                let fill = decode_hex(&o.fill).ok_or(PluginError::NotHex("fill"))?;
                let s = Sculpt {
                    dims: o.dims,
                    bits,
                    fill,
                };
                s.to_grid()?;
                Ok(s)
            }
            _ => Err(PluginError::ShapeOrObject),
        }
    }

    /// A preset of a sculpted object with the given settings.
    pub fn with_object(name: &str, sculpt: &Sculpt) -> Preset {
        Preset {
            name: name.into(),
            description: String::new(),
            shape: None,
            object: Some(StoredObject {
                dims: sculpt.dims,
                voxels: sculpt.bits.iter().map(|b| format!("{b:02x}")).collect(),
                fill: sculpt.fill.iter().map(|b| format!("{b:02x}")).collect(),
            }),
            material: "glass".into(),
            youngs_gpa: None,
            density_kg_m3: None,
            poisson: None,
            size_m: 0.2,
            hardness_ms: 0.5,
            hit: [0.37, 0.41, 1.0],
        }
    }

    /// The voicing the preset sets (material damping, normal strike, 0 dB).
    pub fn voicing(&self) -> Result<Voicing, PluginError> {
        let material = if self.material == "custom" {
            Material::new(
                "custom",
                self.youngs_gpa.unwrap_or(70.0) as f64 * 1e9,
                self.density_kg_m3.unwrap_or(2500.0) as f64,
                self.poisson.unwrap_or(0.25) as f64,
                Material::preset("glass")?.damping,
            )?
        } else {
            Material::preset(&self.material)?
        };
        let mut v =
            Voicing::from_material(&material, self.size_m as f64).ok_or(PluginError::NotLive)?;
        v.hardness_s = self.hardness_ms as f64 * 1e-3;
        v.hit.position = self.hit.map(|c| c as f64);
        Ok(v)
    }

    /// Everything but the object: the material, size, hardness and hit are in range.
    fn check_fields(&self) -> Result<(), PluginError> {
        if self.material_choice().is_none() {
            return Err(PluginError::UnknownMaterial {
                name: self.material.clone(),
                known: MaterialChoice::ids().unwrap_or(&[]).join(", "),
            });
        }
        let out_of_range = |field, value: String, range| PluginError::OutOfRange {
            field,
            value,
            range,
        };
        if !(0.01..=4.0).contains(&self.size_m) {
            return Err(out_of_range("size_m", self.size_m.to_string(), "0.01..4 m"));
        }
        if !(0.0..=20.0).contains(&self.hardness_ms) {
            return Err(out_of_range(
                "hardness_ms",
                self.hardness_ms.to_string(),
                "0..20 ms",
            ));
        }
        if !self.hit.iter().all(|c| (0.0..=1.0).contains(c)) {
            return Err(out_of_range(
                "hit",
                format!("{:?}", self.hit),
                "0..1 (fractions of the extent)",
            ));
        }
        Ok(())
    }
}

fn decode_hex(s: &str) -> Option<Vec<u8>> {
    if !s.len().is_multiple_of(2) {
        return None;
    }
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(s.get(i..i + 2)?, 16).ok())
        .collect()
}
