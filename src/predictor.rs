//! The neural mode predictor's side of the data (issue 12): what the network reads and writes.
//!
//! Where it sits: beside FEM in the worker's solver chain. A shape goes in as a 32^3 occupancy;
//! what comes out is [`bands::BandEncoding`], Deep-Modal's band representation (Jin, Li and
//! Manocha 2020, sec. 3-4: per struck cell and force direction, a mask and a normalised
//! log-amplitude per mel band) plus, per band, the exact frequency of its strongest mode, so a
//! predicted mode is in tune rather than at its band centre. [`bands`] encodes a FEM
//! [`crate::modal::ModeBasis`] into that form (the training labels) and decodes it back to
//! modes a strike plays. The network, its training and the dataset are not built yet.

pub mod bands;
pub mod dataset;
