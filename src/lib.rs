//! ModalForge: a physically based impact-sound instrument.
//!
//! Data flow (see ARCHITECTURE.md): a mode source ([`demo`] today; FEM and a neural predictor
//! later) produces a [`modes::ModeSet`]; [`modes::ModeSet::playable`] culls it for a sample rate;
//! the banks in [`synth`] play it, struck by an [`synth::Excitation`] or driven by a force signal.
#![deny(missing_docs)]

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
