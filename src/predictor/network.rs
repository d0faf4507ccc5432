//! The predictor's network: a small 3D encoder-decoder from a shape's 32^3 fill fractions to its
//! band representation ([`super::bands`]), sized for one CPU core.
//!
//! Where it sits: [`super::Predictor`] runs [`ModeNet::trunk`] once per shape edit (the
//! expensive part) and [`super::Prediction::strike`] per strike (one cell's 1x1 head: microseconds);
//! [`super::train`] fits it with [`ModeNet::loss`].
//!
//! The architecture follows Deep-Modal (Jin et al. 2020, sec. 4.2: an encoder of
//! strided convolutions, a decoder of transposed convolutions with skip connections, a sound
//! feature map at 16^3), made lean for the CPU:
//! - a 2x2x2 patch convolution takes the 32^3 input straight to the 16^3 strike grid;
//! - two strided 3x3x3 convolutions go down to 8^3 and 4^3, a residual block works at 4^3;
//! - a global branch (mean and max over the 4^3 features, beside [`DESCRIPTORS`] shape
//!   descriptors) predicts, per band, whether it holds a mode and where in the band its
//!   strongest mode lies, and conditions the decoder (a mode's band is a property of the whole
//!   shape). Since stop 77 the product takes the bands' presence from
//!   [`super::band_net::BandNet`], the same encoder and global branch trained on presence
//!   alone, and this network's presence logits are a training signal for its head;
//! - two transposed convolutions come back to 16^3, adding the encoder's features at each
//!   scale; a 1x1 head gives, per cell, [`OUT_CHANNELS`] = 3 directions x 32 bands of mask
//!   logits, then as many log-amplitudes. A cell's mask logit is the head's plus its band's
//!   presence logit: a strike's masks are, to 99 %, the bands that hold a mode at all (a
//!   mode within 60 dB of a strike's loudest is heard almost everywhere), so the head only
//!   learns where a band is *not* heard (nodes), and every struck cell teaches the presence.
//!
//! The descriptors are what the physics says sets the pitch: the frequencies of a plate or a
//! shell go as `t / L^2` (thickness over size squared), of a solid as `1 / L`. They are cheap to
//! count from the fills (the volume, the exposed faces, the wall thickness `2 V / faces`, the
//! three extents, sorted so they are the same under the cube's axis permutations) and given in
//! logarithms, where those laws are straight lines; a small network learns them from a few
//! thousand objects far more surely than from pooled convolution features alone.
//!
//! Tensor layout: burn's `[batch, channel, depth, height, width]` with depth = z, height = y,
//! width = x, so a flattened volume is indexed `x + n (y + n z)` as [`super::bands`] indexes
//! its cells.

use super::band_net::BandNet;
use super::bands::{BANDS, CELLS_PER_AXIS, DIRECTIONS, INPUT_SIDE};
use burn::module::{Module, Param};
use burn::nn::conv::{Conv3d, Conv3dConfig, ConvTranspose3d, ConvTranspose3dConfig};
use burn::nn::{Linear, LinearConfig, PaddingConfig3d};
use burn::tensor::activation::{relu, sigmoid};
use burn::tensor::{Device, Tensor};

/// Mask logits per cell: one per direction and band.
pub const MASK_CHANNELS: usize = DIRECTIONS * BANDS;
/// Head outputs per cell: mask logits, then log-amplitudes (same order).
pub const OUT_CHANNELS: usize = 2 * MASK_CHANNELS;
/// Shape descriptors the global branch reads beside the pooled features ([`descriptors`]).
pub const DESCRIPTORS: usize = 6;

/// Channel widths of the network (the shipped weights fix them).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Widths {
    /// Features at 16^3 (the patch convolution and the last decoder stage).
    pub c16: usize,
    /// Features at 8^3.
    pub c8: usize,
    /// Features at 4^3.
    pub c4: usize,
    /// The global branch's hidden width.
    pub global: usize,
    /// Per-cell features the head reads.
    pub head_in: usize,
}

impl Widths {
    /// The shipped network's widths.
    pub const SHIPPED: Widths = Widths {
        c16: 16,
        c8: 32,
        c4: 64,
        global: 128,
        head_in: 32,
    };
}

/// The network (see the module docs).
#[derive(Module, Debug)]
pub struct ModeNet {
    patch: Conv3d,
    down8: Conv3d,
    down4: Conv3d,
    res_a: Conv3d,
    res_b: Conv3d,
    global_hidden: Linear,
    global_bands: Linear,
    global_film: Linear,
    up8: ConvTranspose3d,
    fuse8: Conv3d,
    up16: ConvTranspose3d,
    fuse16: Conv3d,
    head: Conv3d,
}

/// What the network computes once per shape: the per-cell features the head reads, and the
/// per-band answers.
#[derive(Clone, Debug)]
pub struct Trunk {
    /// Per-cell features, `[batch, head_in, 16, 16, 16]`.
    pub features: Tensor<5>,
    /// Per band, the logit that it holds a mode, `[batch, BANDS]`.
    pub band_logit: Tensor<2>,
    /// Per band, where its strongest mode lies in it, 0 (lower edge) to 1 (upper edge) in log
    /// frequency, `[batch, BANDS]`.
    pub band_position: Tensor<2>,
}

fn conv(channels: [usize; 2], kernel: usize, stride: usize, device: &Device) -> Conv3d {
    let pad = if kernel == 3 { 1 } else { 0 };
    Conv3dConfig::new(channels, [kernel; 3])
        .with_stride([stride; 3])
        .with_padding(PaddingConfig3d::Explicit(pad, pad, pad))
        .init(device)
}

fn up(channels: [usize; 2], device: &Device) -> ConvTranspose3d {
    ConvTranspose3dConfig::new(channels, [2; 3])
        .with_stride([2; 3])
        .init(device)
}

impl ModeNet {
    /// A freshly initialised network (random weights, burn's default initialisers).
    pub fn new(widths: Widths, device: &Device) -> Self {
        let Widths {
            c16,
            c8,
            c4,
            global,
            head_in,
        } = widths;
        let [patch, down8, down4, res_a, res_b] = encoder_layers(widths, device);
        Self {
            patch,
            down8,
            down4,
            res_a,
            res_b,
            global_hidden: global_hidden(widths, device),
            global_bands: LinearConfig::new(global, 2 * BANDS).init(device),
            global_film: LinearConfig::new(global, c4).init(device),
            up8: up([c4, c8], device),
            fuse8: conv([c8, c8], 3, 1, device),
            up16: up([c8, c16], device),
            fuse16: conv([c16, head_in], 1, 1, device),
            head: conv([head_in, OUT_CHANNELS], 1, 1, device),
        }
    }

    /// The per-shape part: `fills` is `[batch, 1, 32, 32, 32]` (fill fractions, 0 outside).
    pub fn trunk(&self, fills: Tensor<5>) -> Trunk {
        let shape = descriptors(&fills);
        self.trunk_with(fills, shape)
    }

    /// [`ModeNet::trunk`] with the fills' [`descriptors`] given (computed once where the band
    /// network reads the same fills: 0.3 ms a shape).
    pub fn trunk_with(&self, fills: Tensor<5>, shape: Tensor<2>) -> Trunk {
        let [batch, _, _, _, _] = fills.dims();
        let (encoded, pooled) = Encoder {
            patch: &self.patch,
            down8: &self.down8,
            down4: &self.down4,
            res: [&self.res_a, &self.res_b],
        }
        .forward(fills, shape);
        let [f16, f8, f4] = encoded;
        let c4 = f4.dims()[1];
        let g = relu(self.global_hidden.forward(pooled));
        let bands = self.global_bands.forward(g.clone());
        let band_logit = bands.clone().narrow(1, 0, BANDS);
        let band_position = sigmoid(bands.narrow(1, BANDS, BANDS));
        let film: Tensor<5> = self.global_film.forward(g).reshape([batch, c4, 1, 1, 1]);
        let f4 = f4 + film;
        let d8 = relu(self.fuse8.forward(relu(self.up8.forward(f4) + f8)));
        let d16 = relu(self.up16.forward(d8) + f16);
        let features = relu(self.fuse16.forward(d16));
        Trunk {
            features,
            band_logit,
            band_position,
        }
    }

    /// The band network this network's presence branch is: its encoder, its global hidden
    /// layer and the presence half of its band outputs (the position half dropped). It gives
    /// [`Trunk::band_logit`] exactly. Stop 77's shipped band network was made this way, from
    /// a cell network trained on the presence loss alone (`assets/predictor/README.md`).
    pub fn band_net(&self) -> BandNet {
        let bands = &self.global_bands;
        let presence = Linear {
            weight: Param::from_tensor(bands.weight.val().narrow(1, 0, BANDS)),
            bias: bands
                .bias
                .as_ref()
                .map(|b| Param::from_tensor(b.val().narrow(0, 0, BANDS))),
        };
        BandNet::from_layers(
            [
                self.patch.clone(),
                self.down8.clone(),
                self.down4.clone(),
                self.res_a.clone(),
                self.res_b.clone(),
            ],
            self.global_hidden.clone(),
            presence,
        )
    }

    /// The per-cell head over the whole 16^3 grid: `[batch, OUT_CHANNELS, 16, 16, 16]`, the
    /// band presence logits added to the mask logits (training and scoring; the product
    /// evaluates one cell at a time, `Prediction::strike`).
    pub fn head(&self, trunk: &Trunk) -> Tensor<5> {
        let [batch, _] = trunk.band_logit.dims();
        let logits = trunk.band_logit.clone();
        let presence: Tensor<5> = Tensor::cat(
            vec![logits.clone(); DIRECTIONS]
                .into_iter()
                .chain(vec![logits.zeros_like(); DIRECTIONS])
                .collect(),
            1,
        )
        .reshape([batch, OUT_CHANNELS, 1, 1, 1]);
        self.head.forward(trunk.features.clone()) + presence
    }

    /// The head's weights as a row-major `OUT_CHANNELS x head_in` matrix and its bias, for the
    /// per-cell evaluation on the CPU.
    pub fn head_matrix(&self) -> (Vec<f32>, Vec<f32>) {
        let w = self.head.weight.val();
        let [out, inp, _, _, _] = w.dims();
        let weights = w
            .reshape([out, inp])
            .into_data()
            .try_to_vec::<f32>()
            .expect("f32 weights");
        let bias = match &self.head.bias {
            Some(b) => b.val().into_data().try_to_vec::<f32>().expect("f32 bias"),
            None => vec![0.0; out],
        };
        (weights, bias)
    }

    /// Deep-Modal's loss (eq. 8) over the struck cells, plus the band terms: the mean over
    /// struck cells, directions and bands of the masks' binary cross-entropy and the
    /// log-amplitudes' squared error, plus the bands' presence cross-entropy and the squared
    /// error of their in-band position (bands with a mode only).
    pub fn loss(&self, fills: Tensor<5>, target: &Targets) -> Losses {
        let trunk = self.trunk(fills);
        let out = self.head(&trunk);
        let logits = out.clone().narrow(1, 0, MASK_CHANNELS);
        let amps = out.narrow(1, MASK_CHANNELS, MASK_CHANNELS);
        let struck = target.struck.clone();
        let cells = struck.clone().sum().clamp_min(1.0) * MASK_CHANNELS as f64;
        let mask_bce =
            (bce_with_logits(logits, target.mask.clone()) * struck.clone()).sum() / cells.clone();
        let diff = amps - target.amplitude.clone();
        let amplitude_mse = (diff.clone() * diff * struck).sum() / cells;
        let band_bce = bce_with_logits(trunk.band_logit, target.band_present.clone()).mean();
        let pd = trunk.band_position - target.band_position.clone();
        let present = target.band_present.clone();
        let position_mse = (pd.clone() * pd * present.clone()).sum() / present.sum().clamp_min(1.0);
        Losses {
            mask_bce,
            amplitude_mse,
            band_bce,
            position_mse,
        }
    }
}

/// The encoder [`ModeNet`] and [`super::band_net::BandNet`] share: the patch convolution to
/// 16^3, the strided ones to 8^3 and 4^3, the residual block at 4^3, and the global branch's
/// input (mean and max over the 4^3 features, beside the [`descriptors`]). Each network owns
/// its layers (their names are the weights files' keys); this is the arithmetic.
pub(super) struct Encoder<'a> {
    pub patch: &'a Conv3d,
    pub down8: &'a Conv3d,
    pub down4: &'a Conv3d,
    pub res: [&'a Conv3d; 2],
}

impl Encoder<'_> {
    /// The features at 16^3, 8^3 and 4^3, and the global branch's input
    /// `[batch, 2 c4 + DESCRIPTORS]`; `shape` is the fills' [`descriptors`].
    pub fn forward(&self, fills: Tensor<5>, shape: Tensor<2>) -> ([Tensor<5>; 3], Tensor<2>) {
        let [batch, _, _, _, _] = fills.dims();
        let f16 = relu(self.patch.forward(fills));
        let f8 = relu(self.down8.forward(f16.clone()));
        let f4 = relu(self.down4.forward(f8.clone()));
        let r = relu(self.res[0].forward(f4.clone()));
        let f4 = relu(f4 + self.res[1].forward(r));
        let c4 = f4.dims()[1];
        let flat: Tensor<3> = f4.clone().reshape([batch, c4, 64]);
        let pooled: Tensor<2> = Tensor::cat(
            vec![
                flat.clone().mean_dim(2).reshape([batch, c4]),
                flat.max_dim(2).reshape([batch, c4]),
                shape,
            ],
            1,
        );
        ([f16, f8, f4], pooled)
    }
}

/// Freshly initialised [`Encoder`] layers: the patch convolution (2x2x2 cells of the 32^3
/// input to one 16^3 cell), the strided convolutions to 8^3 and 4^3, the residual block's two.
pub(super) fn encoder_layers(widths: Widths, device: &Device) -> [Conv3d; 5] {
    let Widths { c16, c8, c4, .. } = widths;
    [
        Conv3dConfig::new([1, c16], [2; 3])
            .with_stride([2; 3])
            .init(device),
        conv([c16, c8], 3, 2, device),
        conv([c8, c4], 3, 2, device),
        conv([c4, c4], 3, 1, device),
        conv([c4, c4], 3, 1, device),
    ]
}

/// A freshly initialised global hidden layer: pooled features and descriptors in.
pub(super) fn global_hidden(widths: Widths, device: &Device) -> Linear {
    LinearConfig::new(2 * widths.c4 + DESCRIPTORS, widths.global).init(device)
}

/// The shape descriptors of a batch of fills `[batch, 1, n, n, n]`: `[batch, DESCRIPTORS]`,
/// natural logarithms of the volume (voxels), the exposed faces, the mean wall thickness
/// `2 V / faces` (voxels: a plate's thickness) and the longest, middle and shortest extents
/// (voxels, each the sum over its slices of their largest fill), scaled to about unit range.
pub fn descriptors(fills: &Tensor<5>) -> Tensor<2> {
    let [batch, _, n, _, _] = fills.dims();
    let total = |t: Tensor<5>| t.sum_dims(&[1, 2, 3, 4]).reshape([batch, 1]);
    let volume = total(fills.clone());
    let mut faces = volume.zeros_like();
    for axis in 2..5 {
        let step = fills.clone().narrow(axis, 1, n - 1) - fills.clone().narrow(axis, 0, n - 1);
        faces = faces
            + total(step.abs())
            + total(fills.clone().narrow(axis, 0, 1))
            + total(fills.clone().narrow(axis, n - 1, 1));
    }
    let extent = |axis: usize| {
        let others: Vec<usize> = (2..5).filter(|&a| a != axis).collect();
        total(fills.clone().max_dim(others[0]).max_dim(others[1]))
    };
    let extents: Tensor<2> = Tensor::cat(vec![extent(2), extent(3), extent(4)], 1);
    let longest = extents.clone().max_dim(1);
    let shortest = extents.clone().min_dim(1);
    let middle = extents.sum_dim(1) - longest.clone() - shortest.clone();
    let thickness = volume.clone() * 2.0 / faces.clone().clamp_min(1.0);
    let ln = |t: Tensor<2>, floor: f64, scale: f64| t.clamp_min(floor).log() / scale;
    Tensor::cat(
        vec![
            ln(volume, 1.0, 10.0),
            ln(faces, 1.0, 10.0),
            ln(thickness, 0.25, 3.5),
            ln(longest, 1.0, 3.5),
            ln(middle, 1.0, 3.5),
            ln(shortest, 1.0, 3.5),
        ],
        1,
    )
}

/// Binary cross-entropy from logits, elementwise, in the stable form
/// `max(x, 0) - x y + log(1 + exp(-|x|))`.
pub(super) fn bce_with_logits<const D: usize>(x: Tensor<D>, y: Tensor<D>) -> Tensor<D> {
    x.clone().clamp_min(0.0) - x.clone() * y + x.abs().neg().exp().log1p()
}

/// A batch's targets, laid out as the network's outputs.
#[derive(Clone, Debug)]
pub struct Targets {
    /// 1 for cells with surface, `[batch, 1, 16, 16, 16]`.
    pub struck: Tensor<5>,
    /// Masks, `[batch, MASK_CHANNELS, 16, 16, 16]` (channel = direction x 32 + band).
    pub mask: Tensor<5>,
    /// Normalised log-amplitudes, 0 where the mask is off, same layout.
    pub amplitude: Tensor<5>,
    /// 1 for bands that hold a mode, `[batch, BANDS]`.
    pub band_present: Tensor<2>,
    /// In-band position of each band's strongest mode (0 for empty bands), `[batch, BANDS]`.
    pub band_position: Tensor<2>,
}

/// The loss terms of one batch (scalars, `[1]`).
#[derive(Clone, Debug)]
pub struct Losses {
    /// Masks' binary cross-entropy.
    pub mask_bce: Tensor<1>,
    /// Log-amplitudes' squared error.
    pub amplitude_mse: Tensor<1>,
    /// Band presence cross-entropy.
    pub band_bce: Tensor<1>,
    /// In-band position squared error.
    pub position_mse: Tensor<1>,
}

impl Losses {
    /// The training objective: eq. 8 with `lambda_1 = lambda_2 = 1`, plus the band terms.
    pub fn total(&self) -> Tensor<1> {
        self.mask_bce.clone()
            + self.amplitude_mse.clone()
            + self.band_bce.clone() * 0.1
            + self.position_mse.clone() * POSITION_WEIGHT
    }
}

/// Weight of the in-band position term in [`Losses::total`]. It was 10 (a tenth of a band,
/// ~1.4 semitones at 1 kHz, is a squared error of only 0.01), but the position stayed at the
/// uniform distribution's error (0.08) through every run: at 10 it was two thirds of the loss,
/// and its gradient, noise, swamped the band-presence signal in the shared global branch.
pub const POSITION_WEIGHT: f64 = 1.0;

/// Shapes of the network's input and outputs, checked at compile time against the bands.
const _: () = assert!(INPUT_SIDE == 2 * CELLS_PER_AXIS && CELLS_PER_AXIS == 16);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::predictor::train::{input_of, PERMS};
    use burn::tensor::TensorData;

    #[test]
    fn descriptors_count_a_plate_by_hand_under_every_axis_permutation() {
        // A 20 x 10 x 2 plate: 400 voxels, 2 (200 + 40 + 20) = 520 exposed faces, wall
        // thickness 2 V / faces = 800 / 520, extents 20, 10 and 2, whichever way it lies.
        let plate = crate::shape::VoxelGrid::from_fn([20, 10, 2], 1.0, |_, _, _| true).unwrap();
        let n = INPUT_SIDE;
        let want = [
            400f64.ln() / 10.0,
            520f64.ln() / 10.0,
            (800f64 / 520.0).ln() / 3.5,
            20f64.ln() / 3.5,
            10f64.ln() / 3.5,
            2f64.ln() / 3.5,
        ];
        for perm in PERMS {
            let fills = Tensor::<5>::from_data(
                TensorData::new(input_of(&plate, perm), [1, 1, n, n, n]),
                &Device::flex(),
            );
            let got = descriptors(&fills).into_data().try_to_vec::<f32>().unwrap();
            for (g, w) in got.iter().zip(want) {
                assert!(
                    (*g as f64 - w).abs() < 1e-5,
                    "{perm:?}: {got:?} vs {want:?}"
                );
            }
        }
    }
}
