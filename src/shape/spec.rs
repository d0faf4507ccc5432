//! Shape spec strings, as given to `--shape`.
//!
//! Syntax: `NAME[:PARAMS]` for a built-in shape, or a path ending in `.vox`, `.obj` or `.stl`.
//! PARAMS is a comma-separated list of `key=value` (lengths in voxels), or for `bar`, `plate`
//! and `box` a single `AxBxC`. A trailing `hollow=N` on any built-in keeps an N-voxel shell.
//!
//! | name | keys (defaults) |
//! |---|---|
//! | `bar` | `l=64,w=4,h=4` or `64x4x4` |
//! | `plate` | `l=32,w=32,t=2` or `32x32x2` |
//! | `box` | `x=16,y=16,z=16` or `16x16x16` |
//! | `sphere` | `d=32` |
//! | `cylinder` | `d=16,h=32` |
//! | `tube` | `d=16,h=32,wall=2` |
//! | `bowl` | `d=32,wall=2` (hemispherical shell) |
//! | `cup` | `d=16,h=20,wall=2` |
//! | `bell` | `d=24,h=24,wall=2` |
//!
//! Examples: `bar:64x4x4`, `sphere:d=24`, `bowl:d=32,wall=2`, `box:16x16x16,hollow=2`.

use super::primitives::Primitive;
use super::{ShapeError, VoxelGrid};
use std::path::PathBuf;

/// A parsed `--shape`.
#[derive(Clone, Debug, PartialEq)]
pub enum ShapeSpec {
    /// A built-in primitive, optionally hollowed to a wall of `hollow` voxels (scale 1).
    Primitive {
        /// The shape.
        shape: Primitive,
        /// Hollow to this wall thickness.
        hollow: Option<f64>,
    },
    /// A MagicaVoxel file.
    Vox(PathBuf),
    /// An OBJ or STL mesh.
    Mesh(PathBuf),
}

/// A malformed spec.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SpecError {
    /// Unknown shape name.
    #[error("unknown shape '{0}': use {names}, or a .vox/.obj/.stl file", names = built_in_names())]
    UnknownShape(String),
    /// Unknown key for this shape.
    #[error("shape '{shape}' has no parameter '{key}' (it takes {allowed})")]
    UnknownKey {
        /// Shape name.
        shape: String,
        /// The key.
        key: String,
        /// Keys it accepts.
        allowed: String,
    },
    /// A value is not a positive number.
    #[error("shape parameter '{key}={value}' must be a positive number of voxels")]
    BadValue {
        /// Key.
        key: String,
        /// Value.
        value: String,
    },
    /// A wall is too thick for the shape.
    #[error("wall {wall} voxels is too thick for diameter {diameter}: it must be under half the diameter")]
    WallTooThick {
        /// Wall.
        wall: f64,
        /// Diameter.
        diameter: f64,
    },
}

/// A built-in shape of the spec syntax: its name, its parameters (voxels) with their defaults,
/// and the primitive they make. [`BUILT_INS`] is the one list of shape names: parsing, the
/// errors and the editor's "New" menu read it.
pub struct BuiltIn {
    /// The spec name.
    pub name: &'static str,
    /// Parameter keys, in positional order.
    pub keys: &'static [&'static str],
    /// Their defaults, voxels.
    pub defaults: &'static [f64],
    /// The primitive from the parameters (`keys.len()` of them).
    make: fn(&[f64]) -> Result<Primitive, SpecError>,
}

/// Every built-in shape (the table in the module docs).
pub const BUILT_INS: &[BuiltIn] = &[
    BuiltIn {
        name: "bar",
        keys: &["l", "w", "h"],
        defaults: &[64.0, 4.0, 4.0],
        make: |v| {
            Ok(Primitive::Bar {
                length: v[0],
                width: v[1],
                height: v[2],
            })
        },
    },
    BuiltIn {
        name: "plate",
        keys: &["l", "w", "t"],
        defaults: &[32.0, 32.0, 2.0],
        make: |v| {
            Ok(Primitive::Plate {
                length: v[0],
                width: v[1],
                thickness: v[2],
            })
        },
    },
    BuiltIn {
        name: "box",
        keys: &["x", "y", "z"],
        defaults: &[16.0, 16.0, 16.0],
        make: |v| {
            Ok(Primitive::Box {
                x: v[0],
                y: v[1],
                z: v[2],
            })
        },
    },
    BuiltIn {
        name: "sphere",
        keys: &["d"],
        defaults: &[32.0],
        make: |v| Ok(Primitive::Sphere { diameter: v[0] }),
    },
    BuiltIn {
        name: "cylinder",
        keys: &["d", "h"],
        defaults: &[16.0, 32.0],
        make: |v| {
            Ok(Primitive::Cylinder {
                diameter: v[0],
                height: v[1],
            })
        },
    },
    BuiltIn {
        name: "tube",
        keys: &["d", "h", "wall"],
        defaults: &[16.0, 32.0, 2.0],
        make: |v| {
            check_wall(v[2], v[0])?;
            Ok(Primitive::Tube {
                diameter: v[0],
                height: v[1],
                wall: v[2],
            })
        },
    },
    BuiltIn {
        name: "bowl",
        keys: &["d", "wall"],
        defaults: &[32.0, 2.0],
        make: |v| {
            check_wall(v[1], v[0])?;
            Ok(Primitive::Bowl {
                diameter: v[0],
                wall: v[1],
            })
        },
    },
    BuiltIn {
        name: "cup",
        keys: &["d", "h", "wall"],
        defaults: &[16.0, 20.0, 2.0],
        make: |v| {
            check_wall(v[2], v[0])?;
            Ok(Primitive::Cup {
                diameter: v[0],
                height: v[1],
                wall: v[2],
            })
        },
    },
    BuiltIn {
        name: "bell",
        keys: &["d", "h", "wall"],
        defaults: &[24.0, 24.0, 2.0],
        make: |v| {
            check_wall(v[2], v[0])?;
            Ok(Primitive::Bell {
                diameter: v[0],
                height: v[1],
                wall: v[2],
            })
        },
    },
];

/// The voxels (edge 1) of a built-in primitive at `scale`, hollowed to a wall of `hollow`
/// voxels times `scale` (at least one) where given, for elements that span `block_voxels`
/// voxels per axis ([`Primitive::rasterize_on_blocks`]: odd sides padded and the shape
/// centred, so its mirrors are the mesh's). A hollowed shape is rasterised as it is: the
/// hollowing counts a half-filled face layer as a whole wall voxel.
pub fn primitive_voxels(
    shape: &Primitive,
    hollow: Option<f64>,
    scale: f64,
    block_voxels: usize,
) -> Result<VoxelGrid, ShapeError> {
    match hollow {
        Some(_) => Ok(hollowed(shape.rasterize(scale, 1.0)?, hollow, scale)),
        None => shape.rasterize_on_blocks(scale, 1.0, block_voxels),
    }
}

/// `grid` hollowed to a wall of `hollow` voxels times `scale` (at least one) where given: a
/// spec's `hollow=N` at the scale it was rasterised at.
pub fn hollowed(grid: VoxelGrid, hollow: Option<f64>, scale: f64) -> VoxelGrid {
    match hollow {
        Some(w) => super::ops::hollow(&grid, (w * scale).round().max(1.0) as usize),
        None => grid,
    }
}

/// The built-in names, comma-separated.
pub fn built_in_names() -> String {
    let names: Vec<&str> = BUILT_INS.iter().map(|b| b.name).collect();
    names.join(", ")
}

/// A shell's wall must leave a hollow.
fn check_wall(wall: f64, diameter: f64) -> Result<(), SpecError> {
    if wall * 2.0 >= diameter {
        Err(SpecError::WallTooThick { wall, diameter })
    } else {
        Ok(())
    }
}

/// A positive number of voxels.
fn number(key: &str, value: &str) -> Result<f64, SpecError> {
    match value.trim().parse::<f64>() {
        Ok(x) if x.is_finite() && x > 0.0 => Ok(x),
        _ => Err(SpecError::BadValue {
            key: key.into(),
            value: value.into(),
        }),
    }
}

impl BuiltIn {
    /// The shape from its parameter list (`AxBxC`, `key=value`s, `hollow=N`): the primitive and
    /// the hollow wall.
    fn parse(&self, params: &str) -> Result<(Primitive, Option<f64>), SpecError> {
        let keys = self.keys;
        let mut v = self.defaults.to_vec();
        let mut hollow = None;
        for item in params.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            match item.split_once('=') {
                Some((k, val)) => {
                    let k = k.trim().to_ascii_lowercase();
                    if k == "hollow" {
                        hollow = Some(number(&k, val)?);
                    } else if let Some(i) = keys.iter().position(|&key| key == k) {
                        v[i] = number(&k, val)?;
                    } else {
                        return Err(SpecError::UnknownKey {
                            shape: self.name.into(),
                            key: k,
                            allowed: format!("{}, hollow", keys.join(", ")),
                        });
                    }
                }
                None => {
                    // Positional: `AxBxC` or a single main size.
                    let parts: Vec<&str> = item.split('x').collect();
                    if parts.len() > keys.len() {
                        return Err(SpecError::BadValue {
                            key: keys.join("x"),
                            value: item.into(),
                        });
                    }
                    for (i, p) in parts.iter().enumerate() {
                        v[i] = number(keys[i], p)?;
                    }
                }
            }
        }
        Ok(((self.make)(&v)?, hollow))
    }
}

impl std::str::FromStr for ShapeSpec {
    type Err = SpecError;

    fn from_str(s: &str) -> Result<Self, SpecError> {
        let lower = s.to_ascii_lowercase();
        if lower.ends_with(".vox") {
            return Ok(ShapeSpec::Vox(s.into()));
        }
        if lower.ends_with(".obj") || lower.ends_with(".stl") {
            return Ok(ShapeSpec::Mesh(s.into()));
        }
        let (name, params) = s.split_once(':').unwrap_or((s, ""));
        let name = name.trim().to_ascii_lowercase();
        let built_in = BUILT_INS
            .iter()
            .find(|b| b.name == name)
            .ok_or(SpecError::UnknownShape(name))?;
        let (shape, hollow) = built_in.parse(params)?;
        Ok(ShapeSpec::Primitive { shape, hollow })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_positional_and_keyed_parameters() {
        let s: ShapeSpec = "bar:64x4x4".parse().unwrap();
        assert_eq!(
            s,
            ShapeSpec::Primitive {
                shape: Primitive::Bar {
                    length: 64.0,
                    width: 4.0,
                    height: 4.0
                },
                hollow: None
            }
        );
        let s: ShapeSpec = "bowl:d=20,wall=3".parse().unwrap();
        assert!(matches!(
            s,
            ShapeSpec::Primitive {
                shape: Primitive::Bowl { diameter, wall },
                ..
            } if diameter == 20.0 && wall == 3.0
        ));
        assert!(matches!(
            "x/y.VOX".parse::<ShapeSpec>().unwrap(),
            ShapeSpec::Vox(_)
        ));
    }

    #[test]
    fn bad_specs_say_what_is_wrong() {
        for (spec, needle) in [
            ("teapot", "unknown shape"),
            ("sphere:r=3", "no parameter 'r'"),
            ("bar:64x-4x4", "positive number"),
            ("bowl:d=8,wall=4", "too thick"),
            ("sphere:d=nan", "positive number"),
        ] {
            let e = spec.parse::<ShapeSpec>().unwrap_err().to_string();
            assert!(e.contains(needle), "{spec}: {e}");
        }
    }
}
