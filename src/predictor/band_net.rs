//! The band network: which of the 32 bands hold a mode, from a shape's 32^3 fills, trained on
//! that question alone.
//!
//! Where it sits: [`super::Predictor`] runs it beside [`ModeNet`](super::network::ModeNet)
//! once per shape edit, and its logits replace the cell network's band presence logits
//! ([`super::Nets`]); [`super::train`] fits it (`modalforge train --bands-only`).
//!
//! Why a network of its own. A strike's masks are, to 99 %, the bands that hold a mode at all
//! (`network`'s module docs), so band presence is the whole of the masks' recall and
//! precision, and stop 76 found the cell network underfitting it: as good on unseen objects
//! as on its own training objects. Stop 77 measured why: a deeper, wider trunk (two residual
//! blocks more, a 2^3 stage, 1.2M parameters) and group norms left the training loss where it
//! was, epoch for epoch; what it lacked was steps. The cell network's step is mostly its
//! 16^3 decoder and the per-cell loss (`[batch, 192, 16^3]` outputs); this network is the same
//! encoder and global branch without them, 8x cheaper per object, so the same hours on the
//! CPU give it 8x the epochs, and its presence beats the cell network's (the figures are in
//! `assets/predictor/README.md`).
//!
//! Architecture: [`network::Encoder`](super::network) (patch convolution to 16^3, strided
//! convolutions to 8^3 and 4^3, a residual block, mean and max pooled beside the six shape
//! descriptors), one hidden layer, 32 presence logits. Loss: the presence cross-entropy
//! (Deep-Modal eq. 8's mask term, per band instead of per cell).

use super::bands::BANDS;
use super::network::{
    bce_with_logits, descriptors, encoder_layers, global_hidden, Encoder, Widths,
};
use burn::module::Module;
use burn::nn::conv::Conv3d;
use burn::nn::{Linear, LinearConfig};
use burn::tensor::activation::relu;
use burn::tensor::{Device, Tensor};

/// The band network (see the module docs). Its layers carry the cell network's names, so
/// a weights file says which layer is which the same way in both.
#[derive(Module, Debug)]
pub struct BandNet {
    patch: Conv3d,
    down8: Conv3d,
    down4: Conv3d,
    res_a: Conv3d,
    res_b: Conv3d,
    global_hidden: Linear,
    global_bands: Linear,
}

impl BandNet {
    /// A freshly initialised network (random weights, burn's default initialisers), with the
    /// encoder and global widths of `widths` (the decoder's are unused).
    pub fn new(widths: Widths, device: &Device) -> Self {
        Self::from_layers(
            encoder_layers(widths, device),
            global_hidden(widths, device),
            LinearConfig::new(widths.global, BANDS).init(device),
        )
    }

    /// A band network of given layers ([`ModeNet::band_net`](super::network::ModeNet::band_net)).
    pub(super) fn from_layers(
        encoder: [Conv3d; 5],
        global_hidden: Linear,
        global_bands: Linear,
    ) -> Self {
        let [patch, down8, down4, res_a, res_b] = encoder;
        Self {
            patch,
            down8,
            down4,
            res_a,
            res_b,
            global_hidden,
            global_bands,
        }
    }

    /// Per band, the logit that it holds a mode: `fills` `[batch, 1, 32, 32, 32]` in,
    /// `[batch, BANDS]` out.
    pub fn logits(&self, fills: Tensor<5>) -> Tensor<2> {
        let shape = descriptors(&fills);
        self.logits_with(fills, shape)
    }

    /// [`BandNet::logits`] with the fills' [`descriptors`] given (computed once where the cell
    /// network reads the same fills).
    pub fn logits_with(&self, fills: Tensor<5>, shape: Tensor<2>) -> Tensor<2> {
        let (_, pooled) = Encoder {
            patch: &self.patch,
            down8: &self.down8,
            down4: &self.down4,
            res: [&self.res_a, &self.res_b],
        }
        .forward(fills, shape);
        self.global_bands
            .forward(relu(self.global_hidden.forward(pooled)))
    }

    /// The training loss: the mean presence cross-entropy over the batch's bands; `present`
    /// is `[batch, BANDS]`, 1 where the band holds a mode.
    pub fn loss(&self, fills: Tensor<5>, present: Tensor<2>) -> Tensor<1> {
        bce_with_logits(self.logits(fills), present).mean()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::predictor::network::ModeNet;
    use crate::predictor::train::{input_of, PERMS};
    use burn::tensor::TensorData;

    #[test]
    fn a_band_net_with_the_cell_networks_layers_gives_its_presence_logits() {
        // The two networks share the encoder arithmetic (`network::Encoder`); a band network
        // carrying a cell network's encoder and global layers must give that network's band
        // logits exactly (the position half of the outputs kept instead of the presence
        // half, a layer swapped or an activation missing in either would not).
        let device = Device::flex();
        let cells = ModeNet::new(Widths::SHIPPED, &device);
        let bands = cells.band_net();
        let plate = crate::shape::VoxelGrid::from_fn([20, 10, 2], 1.0, |_, _, _| true).unwrap();
        let n = crate::predictor::bands::INPUT_SIDE;
        let fills = Tensor::<5>::from_data(
            TensorData::new(input_of(&plate, PERMS[3]), [1, 1, n, n, n]),
            &device,
        );
        let want = cells.trunk(fills.clone()).band_logit.into_data();
        let got = bands.logits(fills).into_data();
        let (want, got) = (
            want.try_to_vec::<f32>().unwrap(),
            got.try_to_vec::<f32>().unwrap(),
        );
        assert_eq!(want.len(), BANDS);
        for (w, g) in want.iter().zip(&got) {
            assert!(
                (w - g).abs() <= 1e-5 * (1.0 + w.abs()),
                "{want:?} vs {got:?}"
            );
        }
    }
}
