//! Materials: elastic constants plus a damping model.
//!
//! Where it sits: beside the shape, the second input of the modal pipeline. The FEM uses Young's
//! modulus `E`, density `rho` and Poisson's ratio `nu`; [`damping`] turns each eigenvalue into a
//! decay rate and damped frequency. Presets live in `presets/materials/*.toml` (each cites its
//! source) and are compiled into the binary, so `--material steel` works from any directory.
//!
//! TOML schema:
//! ```toml
//! name = "steel"
//! source = "where the numbers come from"
//! youngs_modulus_pa = 2.0e11
//! density_kg_m3 = 7850.0
//! poisson_ratio = 0.29
//! damping = "rayleigh"          # the default model: rayleigh | caughey | power_law
//! [rayleigh]
//! alpha1 = 5.0                  # 1/s
//! alpha2 = 3e-8                 # s
//! [caughey]                     # optional
//! eta = [280.0, -3.6e-7, 2.0e-15]
//! [power_law]                   # optional
//! mu1 = 1.13
//! mu2 = 0.3
//! ```

pub mod damping;

pub use damping::{DampedMode, Damping, DampingLaw};
use serde::{Deserialize, Serialize};

/// A material: elastic constants and damping.
#[derive(Clone, Debug)]
pub struct Material {
    /// Name (preset name, or `custom`).
    pub name: String,
    /// Young's modulus `E`, Pa.
    pub youngs_modulus_pa: f64,
    /// Density `rho`, kg/m^3.
    pub density_kg_m3: f64,
    /// Poisson's ratio `nu`, in (-1, 0.5).
    pub poisson_ratio: f64,
    /// The damping model used.
    pub damping: Damping,
    /// Where the numbers come from.
    pub source: String,
    /// Every damping model the preset provides, by name (`rayleigh`, `caughey`, `power_law`).
    pub damping_models: Vec<(String, Damping)>,
}

/// What is wrong with a material.
#[derive(Debug, thiserror::Error)]
pub enum MaterialError {
    /// `E` not positive.
    #[error("Young's modulus E = {0} Pa must be a positive finite number (steel is 2e11)")]
    BadYoungsModulus(f64),
    /// `rho` not positive.
    #[error("density rho = {0} kg/m^3 must be a positive finite number (steel is 7850)")]
    BadDensity(f64),
    /// `nu` outside (-1, 0.5).
    #[error(
        "Poisson's ratio nu = {0} must lie in (-1, 0.5): at 0.5 a solid is incompressible and \
         the elasticity matrix is singular"
    )]
    BadPoisson(f64),
    /// A damping parameter is not finite.
    #[error("damping parameter {name} = {value} must be a finite number")]
    BadDamping {
        /// Parameter.
        name: &'static str,
        /// Value.
        value: f64,
    },
    /// No such preset.
    #[error("unknown material '{0}': use one of {list}, or E,RHO,NU[,ALPHA1,ALPHA2] in SI units", list = preset_names().join(", "))]
    Unknown(String),
    /// The file is larger than [`crate::limits::MAX_TEXT_BYTES`].
    #[error(transparent)]
    FileTooLarge(crate::limits::FileTooLarge),
    /// The TOML could not be parsed.
    #[error("material file {name}: {reason}")]
    Toml {
        /// File name.
        name: String,
        /// Parser message.
        reason: String,
    },
    /// The file names a damping model it does not define.
    #[error("material file {name}: damping = \"{model}\" but there is no [{model}] table")]
    MissingModel {
        /// File name.
        name: String,
        /// Model name.
        model: String,
    },
}

#[derive(Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct MaterialFile {
    name: String,
    source: String,
    youngs_modulus_pa: f64,
    density_kg_m3: f64,
    poisson_ratio: f64,
    damping: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    rayleigh: Option<RayleighToml>,
    #[serde(skip_serializing_if = "Option::is_none")]
    caughey: Option<CaugheyToml>,
    #[serde(skip_serializing_if = "Option::is_none")]
    power_law: Option<PowerToml>,
}

#[derive(Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct RayleighToml {
    alpha1: f64,
    alpha2: f64,
}

#[derive(Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct CaugheyToml {
    eta: Vec<f64>,
}

#[derive(Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct PowerToml {
    mu1: f64,
    mu2: f64,
}

macro_rules! presets {
    ($($name:literal),* $(,)?) => {
        /// The preset files compiled into the binary: `(name, TOML text)`.
        pub const PRESETS: &[(&str, &str)] = &[
            $(($name, include_str!(concat!("../presets/materials/", $name, ".toml"))),)*
        ];
    };
}

presets!(
    "ceramic",
    "glass",
    "wood",
    "plastic",
    "iron",
    "steel",
    "aluminium",
    "brass",
    "polycarbonate",
    "tin",
    "sl-plastic-1",
    "sl-plastic-2",
    "sl-porcelain",
    "sl-wood",
    "sl-aluminum",
);

/// Names of the presets.
pub fn preset_names() -> Vec<&'static str> {
    PRESETS.iter().map(|(n, _)| *n).collect()
}

impl Material {
    /// A material with Rayleigh damping, validated.
    pub fn new(
        name: &str,
        youngs_modulus_pa: f64,
        density_kg_m3: f64,
        poisson_ratio: f64,
        damping: Damping,
    ) -> Result<Self, MaterialError> {
        let m = Material {
            name: name.into(),
            youngs_modulus_pa,
            density_kg_m3,
            poisson_ratio,
            damping: damping.clone(),
            source: "user".into(),
            damping_models: vec![("custom".into(), damping)],
        };
        m.validate()?;
        Ok(m)
    }

    /// Checks the constants and damping parameters.
    pub fn validate(&self) -> Result<(), MaterialError> {
        let e = self.youngs_modulus_pa;
        if !(e.is_finite() && e > 0.0) {
            return Err(MaterialError::BadYoungsModulus(e));
        }
        let rho = self.density_kg_m3;
        if !(rho.is_finite() && rho > 0.0) {
            return Err(MaterialError::BadDensity(rho));
        }
        let nu = self.poisson_ratio;
        if !(nu.is_finite() && nu > -1.0 && nu < 0.5) {
            return Err(MaterialError::BadPoisson(nu));
        }
        for (_, d) in &self.damping_models {
            let params: Vec<(&'static str, f64)> = match d {
                Damping::Rayleigh { alpha1, alpha2 } => {
                    vec![("alpha1", *alpha1), ("alpha2", *alpha2)]
                }
                Damping::Caughey { eta } => eta.iter().map(|&e| ("eta", e)).collect(),
                Damping::PowerLaw { mu1, mu2 } => vec![("mu1", *mu1), ("mu2", *mu2)],
                Damping::Custom(_) => vec![],
            };
            if let Some(&(name, value)) = params.iter().find(|(_, v)| !v.is_finite()) {
                return Err(MaterialError::BadDamping { name, value });
            }
        }
        Ok(())
    }

    /// The material as a TOML file [`Material::from_toml`] reads back (every damping model it
    /// holds, the one in use named); `None` when the damping in use is a custom function,
    /// which a file cannot hold.
    pub fn to_toml(&self) -> Option<String> {
        let mut file = MaterialFile {
            name: self.name.clone(),
            source: self.source.clone(),
            youngs_modulus_pa: self.youngs_modulus_pa,
            density_kg_m3: self.density_kg_m3,
            poisson_ratio: self.poisson_ratio,
            damping: self.damping.law()?.to_string(),
            rayleigh: None,
            caughey: None,
            power_law: None,
        };
        let models = self
            .damping_models
            .iter()
            .map(|(_, d)| d)
            .chain(std::iter::once(&self.damping));
        for d in models {
            match d {
                Damping::Rayleigh { alpha1, alpha2 } => {
                    file.rayleigh = Some(RayleighToml {
                        alpha1: *alpha1,
                        alpha2: *alpha2,
                    })
                }
                Damping::Caughey { eta } => file.caughey = Some(CaugheyToml { eta: eta.clone() }),
                Damping::PowerLaw { mu1, mu2 } => {
                    file.power_law = Some(PowerToml {
                        mu1: *mu1,
                        mu2: *mu2,
                    })
                }
                Damping::Custom(_) => {}
            }
        }
        Some(toml::to_string(&file).expect("a material serialises"))
    }

    /// Parses a material TOML file (schema in the module docs).
    pub fn from_toml(text: &str, file_name: &str) -> Result<Self, MaterialError> {
        let f: MaterialFile = toml::from_str(text).map_err(|e| MaterialError::Toml {
            name: file_name.into(),
            reason: e.message().to_string(),
        })?;
        let mut models = Vec::new();
        if let Some(r) = f.rayleigh {
            models.push((
                DampingLaw::Rayleigh.to_string(),
                Damping::Rayleigh {
                    alpha1: r.alpha1,
                    alpha2: r.alpha2,
                },
            ));
        }
        if let Some(c) = f.caughey {
            models.push((
                DampingLaw::Caughey.to_string(),
                Damping::Caughey { eta: c.eta },
            ));
        }
        if let Some(p) = f.power_law {
            models.push((
                DampingLaw::PowerLaw.to_string(),
                Damping::PowerLaw {
                    mu1: p.mu1,
                    mu2: p.mu2,
                },
            ));
        }
        let damping = models
            .iter()
            .find(|(n, _)| *n == f.damping)
            .map(|(_, d)| d.clone())
            .ok_or_else(|| MaterialError::MissingModel {
                name: file_name.into(),
                model: f.damping.clone(),
            })?;
        let m = Material {
            name: f.name,
            youngs_modulus_pa: f.youngs_modulus_pa,
            density_kg_m3: f.density_kg_m3,
            poisson_ratio: f.poisson_ratio,
            damping,
            source: f.source,
            damping_models: models,
        };
        m.validate()?;
        Ok(m)
    }

    /// A built-in preset by name (case-insensitive).
    pub fn preset(name: &str) -> Result<Self, MaterialError> {
        let lower = name.trim().to_ascii_lowercase();
        let (file, text) = PRESETS
            .iter()
            .find(|(n, _)| *n == lower)
            .ok_or_else(|| MaterialError::Unknown(name.into()))?;
        Self::from_toml(text, &format!("presets/materials/{file}.toml"))
    }

    /// Parses `--material`: a preset name, a path to a `.toml` file, or `E,RHO,NU[,ALPHA1,ALPHA2]`
    /// (SI units; Rayleigh damping, zero when omitted).
    pub fn parse(spec: &str) -> Result<Self, MaterialError> {
        if spec.to_ascii_lowercase().ends_with(".toml") {
            let text = crate::limits::read_text(std::path::Path::new(spec), "material TOML")
                .map_err(|e| match e {
                    crate::limits::TextReadError::TooLarge(e) => MaterialError::FileTooLarge(e),
                    crate::limits::TextReadError::Io(e) => MaterialError::Toml {
                        name: spec.into(),
                        reason: e.to_string(),
                    },
                })?;
            return Self::from_toml(&text, spec);
        }
        if spec.contains(',') {
            let nums: Vec<f64> = spec
                .split(',')
                .map(|s| s.trim().parse::<f64>().unwrap_or(f64::NAN))
                .collect();
            if nums.len() != 3 && nums.len() != 5 {
                return Err(MaterialError::Unknown(spec.into()));
            }
            let (a1, a2) = if nums.len() == 5 {
                (nums[3], nums[4])
            } else {
                (0.0, 0.0)
            };
            return Self::new(
                "custom",
                nums[0],
                nums[1],
                nums[2],
                Damping::Rayleigh {
                    alpha1: a1,
                    alpha2: a2,
                },
            );
        }
        Self::preset(spec)
    }

    /// Selects one of the preset's damping models by its law.
    pub fn with_damping_law(mut self, law: DampingLaw) -> Option<Self> {
        let d = self
            .damping_models
            .iter()
            .find(|(_, d)| d.law() == Some(law))?
            .1
            .clone();
        self.damping = d;
        Some(self)
    }

    /// Shear wave speed `sqrt(G / rho)`, m/s: sets the shortest wavelength the mesh must resolve.
    pub fn shear_wave_speed_m_s(&self) -> f64 {
        let g = self.youngs_modulus_pa / (2.0 * (1.0 + self.poisson_ratio));
        (g / self.density_kg_m3).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_preset_parses_and_cites_a_source() {
        for name in preset_names() {
            let m = Material::preset(name).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert!(m.source.len() > 20, "{name} needs a citation");
            assert!(!m.damping_models.is_empty());
        }
        // Sterling & Lin's measured materials carry all three fitted models (Sterling and Lin 2016,
        // Table 1).
        for name in [
            "sl-plastic-1",
            "sl-plastic-2",
            "sl-porcelain",
            "sl-wood",
            "sl-aluminum",
        ] {
            assert_eq!(
                Material::preset(name).unwrap().damping_models.len(),
                3,
                "{name}"
            );
        }
    }

    #[test]
    fn impossible_materials_are_refused() {
        for (spec, needle) in [
            ("2e11,7850,0.5", "Poisson"),
            ("0,7850,0.3", "Young"),
            ("2e11,-1,0.3", "density"),
            ("2e11,7850,nan", "Poisson"),
            ("unobtainium", "unknown material"),
            ("2e11,7850,0.3,inf,0", "damping"),
        ] {
            let e = Material::parse(spec).unwrap_err().to_string();
            assert!(e.contains(needle), "{spec}: {e}");
        }
        assert!(Material::parse("2e11,7850,0.3").is_ok());
    }

    /// Every preset survives `to_toml` and `from_toml` unchanged: constants, the damping in
    /// use and every model it offers.
    #[test]
    fn materials_round_trip_through_toml() {
        for name in preset_names() {
            let m = Material::preset(name).unwrap();
            let text = m.to_toml().expect("presets use named laws");
            let back = Material::from_toml(&text, name).unwrap();
            assert_eq!(back.youngs_modulus_pa, m.youngs_modulus_pa, "{name}");
            assert_eq!(back.density_kg_m3, m.density_kg_m3, "{name}");
            assert_eq!(back.poisson_ratio, m.poisson_ratio, "{name}");
            assert_eq!(back.damping.law(), m.damping.law(), "{name}");
            for w in [1e3, 1e6, 1e9] {
                assert_eq!(
                    back.damping.coefficient(w),
                    m.damping.coefficient(w),
                    "{name}"
                );
            }
            assert_eq!(
                back.damping_models.len(),
                m.damping_models.len(),
                "{name}\n{text}"
            );
        }
    }
}
