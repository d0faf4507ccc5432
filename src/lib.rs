//! ModalForge: a physically based impact-sound instrument.
//!
//! Data flow (see ARCHITECTURE.md): a shape ([`shape`]: voxels, partial where a curved surface
//! cuts them) is assembled by [`fem`] and solved by [`eigen`] into a [`modal::ModeBasis`]; that,
//! a mode file or the analytic [`demo`] bar becomes a [`modes::ModeSet`];
//! [`modes::ModeSet::playable`] culls it for a sample rate; the banks in [`synth`] play it,
//! struck by an [`synth::Excitation`] or driven by a force signal, offline (the [`cli`]) or in
//! real time ([`engine`], which the plugin and the standalone app run). [`predictor`] holds the
//! neural predictor's data representation and training set (its network is not built yet).
#![deny(missing_docs)]

pub mod analysis;
pub mod buffer;
pub mod cli;
pub mod demo;
pub mod eigen;
pub mod engine;
pub mod fem;
pub mod material;
pub mod modal;
pub mod modes;
pub mod predictor;
pub mod shape;
pub mod synth;

/// Writes a `clap::ValueEnum`'s command-line name, honouring width and alignment: the one
/// source of the names that `--help` lists, that reports print and that `Display` shows.
pub(crate) fn cli_name<T: clap::ValueEnum>(
    value: &T,
    f: &mut std::fmt::Formatter<'_>,
) -> std::fmt::Result {
    match value.to_possible_value() {
        Some(v) => f.pad(v.get_name()),
        None => f.pad("(hidden)"),
    }
}
