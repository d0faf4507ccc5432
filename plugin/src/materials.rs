//! The material presets as a parameter and as a table the audio thread can read without
//! allocating (a [`Material`] holds strings and vectors; the table holds only numbers).

use modalforge::engine::DampingParams;
use modalforge::material::Material;
use nice_plug::prelude::Enum;

/// The material parameter's choices: the presets in `presets/materials/`, then "Custom".
#[derive(Enum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum MaterialChoice {
    /// Steel.
    #[id = "steel"]
    #[name = "Steel"]
    Steel,
    /// Iron.
    #[id = "iron"]
    #[name = "Iron"]
    Iron,
    /// Aluminium.
    #[id = "aluminium"]
    #[name = "Aluminium"]
    Aluminium,
    /// Brass.
    #[id = "brass"]
    #[name = "Brass"]
    Brass,
    /// Tin.
    #[id = "tin"]
    #[name = "Tin"]
    Tin,
    /// Glass.
    #[id = "glass"]
    #[name = "Glass"]
    Glass,
    /// Ceramic.
    #[id = "ceramic"]
    #[name = "Ceramic"]
    Ceramic,
    /// Wood.
    #[id = "wood"]
    #[name = "Wood"]
    Wood,
    /// Plastic.
    #[id = "plastic"]
    #[name = "Plastic"]
    Plastic,
    /// Polycarbonate.
    #[id = "polycarbonate"]
    #[name = "Polycarbonate"]
    Polycarbonate,
    /// Measured aluminium (Sterling and Lin 2016, Table 1).
    #[id = "sl-aluminum"]
    #[name = "Aluminium (measured)"]
    SlAluminum,
    /// Measured plastic 1.
    #[id = "sl-plastic-1"]
    #[name = "Plastic 1 (measured)"]
    SlPlastic1,
    /// Measured plastic 2.
    #[id = "sl-plastic-2"]
    #[name = "Plastic 2 (measured)"]
    SlPlastic2,
    /// Measured porcelain.
    #[id = "sl-porcelain"]
    #[name = "Porcelain (measured)"]
    SlPorcelain,
    /// Measured wood.
    #[id = "sl-wood"]
    #[name = "Wood (measured)"]
    SlWood,
    /// The E, Density and Poisson knobs.
    #[id = "custom"]
    #[name = "Custom"]
    Custom,
}

/// One preset's numbers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PresetNumbers {
    /// Pa.
    pub youngs_modulus_pa: f64,
    /// kg/m^3.
    pub density_kg_m3: f64,
    /// Poisson's ratio.
    pub poisson_ratio: f64,
    /// The preset's default damping model.
    pub damping: DampingParams,
}

/// Every choice's numbers, indexed by [`Enum::to_index`] ("Custom" holds glass's damping).
pub struct MaterialTable {
    rows: Vec<PresetNumbers>,
}

impl MaterialTable {
    /// Reads the compiled-in presets. Allocates (called once, off the audio thread).
    pub fn new() -> Self {
        let rows = MaterialChoice::variants()
            .iter()
            .enumerate()
            .map(|(i, _)| {
                let id = MaterialChoice::ids().map_or("glass", |ids| ids[i]);
                let m = Material::preset(if id == "custom" { "glass" } else { id })
                    .unwrap_or_else(|e| panic!("preset {id} is compiled in: {e}"));
                PresetNumbers {
                    youngs_modulus_pa: m.youngs_modulus_pa,
                    density_kg_m3: m.density_kg_m3,
                    poisson_ratio: m.poisson_ratio,
                    damping: DampingParams::from_damping(&m.damping).unwrap_or(
                        DampingParams::Rayleigh {
                            alpha1: 1.0,
                            alpha2: 1e-7,
                        },
                    ),
                }
            })
            .collect();
        Self { rows }
    }

    /// The numbers of a choice. Never allocates.
    pub fn get(&self, choice: MaterialChoice) -> &PresetNumbers {
        &self.rows[choice.to_index()]
    }
}

impl Default for MaterialTable {
    fn default() -> Self {
        Self::new()
    }
}
