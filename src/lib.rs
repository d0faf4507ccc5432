//! ModalForge: a physically based impact-sound instrument.
//!
//! Data flow (see ARCHITECTURE.md): a shape ([`shape`]: voxels, partial where a curved surface
//! cuts them) is assembled by [`fem`] and solved by [`eigen`] into a [`basis::ModeBasis`] (the
//! expensive shape solve); the neural [`predictor`] gives an approximate one in milliseconds.
//! Voicing a basis with a material, a size and a strike gives a [`modes::ModeSet`] (so does a
//! mode file, the analytic [`demo`] bar, or [`analysis`] of a recording);
//! [`modes::ModeSet::playable`] culls it for a sample rate; the banks in [`synth`] play it,
//! struck by an [`synth::Excitation`] or driven by a force signal, offline (the `modalforge`
//! command line, `src/cli.rs` in the binary) or in real time ([`engine`], which the plugin
//! and the standalone app run).
//!
//! # Example: solve a bar, strike it, render a block
//!
//! ```
//! use modalforge::eigen::{EigenOptions, ModeCount, SolverKind};
//! use modalforge::fem::ElementKind;
//! use modalforge::material::Material;
//! use modalforge::basis::ModeBasis;
//! use modalforge::modes::CullSettings;
//! use modalforge::shape::primitives::Primitive;
//! use modalforge::synth::{Excitation, OscillatorBank};
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! // A steel bar of 64 x 4 x 4 voxels of 5 mm: 0.32 m long, 2 cm square.
//! let (length_m, side_m) = (0.32, 0.02);
//! let bar = Primitive::Bar { length: 64.0, width: 4.0, height: 4.0 }.rasterize(1.0, 0.005)?;
//! let steel = Material::preset("steel")?;
//!
//! // The shape solve (off the audio thread; it allocates and takes milliseconds to seconds).
//! let options = EigenOptions { count: ModeCount::First(8), ..Default::default() };
//! let basis = ModeBasis::solve(
//!     &bar,
//!     ElementKind::Hex8Incompatible,
//!     steel.poisson_ratio,
//!     SolverKind::Lanczos,
//!     &options,
//! )?;
//!
//! // The voicing (cheap): material, size and strike give frequencies, decays and gains.
//! let hit = basis.default_hit(bar.voxel_size_m());
//! let modes = basis.mode_set(&steel, bar.voxel_size_m(), &hit)?;
//!
//! // The lowest mode is the free-free bending mode: Euler-Bernoulli gives
//! // f1 = 4.730^2 / (2 pi L^2) sqrt(E I / (rho A)), I / A = side^2 / 12 (1013 Hz). A beam 16
//! // sides long is about 1 % softer (shear and rotary inertia, Timoshenko): 3 % bound.
//! let beam_hz = 4.730f64.powi(2) / (std::f64::consts::TAU * length_m * length_m)
//!     * (steel.youngs_modulus_pa / steel.density_kg_m3 * side_m * side_m / 12.0).sqrt();
//! let f1 = modes.freq_hz()[0];
//! assert!((f1 / beam_hz - 1.0).abs() < 0.03, "{f1} Hz against {beam_hz} Hz");
//!
//! // Playing. The real-time contract of every bank: construction allocates; `strike`,
//! // `render` and `reset` never allocate, lock, block or log, so they may run on the audio
//! // thread (the engine swaps new banks in through a wait-free ring; `engine` says how).
//! let (playable, _culled) = modes.playable(48_000.0, &CullSettings::default())?;
//! let mut bank = OscillatorBank::new(&playable);
//! bank.strike(Excitation::Impulse, 1.0)?;
//! let mut block = [0f32; 64];
//! bank.render(&mut block);
//! assert!(block.iter().all(|x| x.is_finite()) && block.iter().any(|&x| x != 0.0));
//! # Ok(())
//! # }
//! ```
#![deny(missing_docs)]

pub mod analysis;
pub mod basis;
pub(crate) mod buffer;
pub mod demo;
pub mod eigen;
pub mod engine;
pub mod fem;
pub(crate) mod fma;
pub mod limits;
pub mod material;
pub mod modes;
pub mod predictor;
pub mod rng;
pub mod shape;
pub mod synth;
pub mod tuning;

/// Writes a `clap::ValueEnum`'s command-line name, honouring width and alignment: the one
/// source of the names that `--help` lists, that reports print and that `Display` shows
/// (the library's enums and the binary's `--solver` choice implement `Display` with it).
pub fn cli_name<T: clap::ValueEnum>(
    value: &T,
    f: &mut std::fmt::Formatter<'_>,
) -> std::fmt::Result {
    match value.to_possible_value() {
        Some(v) => f.pad(v.get_name()),
        None => f.pad("(hidden)"),
    }
}
