//! Editor logic without a window, one file per concern: sculpting (`tests/sculpting.rs`),
//! the 3D view and picking (`view.rs`), the window's layout and status (`window.rs`), files
//! and state (`files.rs`), recordings (`recordings.rs`) and tunings (`tuning.rs`); here, the
//! helpers they share: a block-shaped sculpt, an app around it, a host that applies every
//! parameter change at once, and a camera looking straight at the front face.

use super::sculptor::{Sculptor, BOX_SIDE};
use super::view3d::{self, Camera, NORMALS};
use super::*;
use crate::materials::MaterialChoice;
use modalforge::shape::VoxelFill;
use nice_plug::prelude::*;

fn block(dims: [usize; 3]) -> Sculpt {
    let grid = modalforge::shape::VoxelGrid::from_fn(dims, 1.0, |_, _, _| true).unwrap();
    Sculpt::from_grid(&grid)
}

fn app_with(sculpt: Sculpt) -> EditorApp {
    let params = Arc::new(ModalForgeParams::default());
    *params.object.write().unwrap() = sculpt;
    EditorApp::new(
        params,
        Arc::new(MaterialTable::new()),
        Arc::new(EditorLink::default()),
    )
}

/// A host for editor tests: applies every parameter change the editor makes at once (as a
/// host does when nothing automates the parameter) and counts the gestures. The real hosts
/// are tested by `plugin/tests/host_test.py`; this one lets the editor's own code that talks
/// to the host run without a window.
#[derive(Default)]
struct TestHost {
    gestures: std::sync::atomic::AtomicUsize,
}

impl GuiContextInner for TestHost {
    fn plugin_api(&self) -> PluginApi {
        PluginApi::Clap
    }
    unsafe fn raw_begin_set_parameter(&self, _param: ParamPtr) {
        self.gestures.fetch_add(1, Ordering::Relaxed);
    }
    unsafe fn raw_set_parameter_normalized(&self, param: ParamPtr, normalized: f32) {
        // SAFETY: the parameters the editor sets live in the `ModalForgeParams` the test holds
        // for the whole call.
        unsafe {
            param._internal_set_normalized_value(normalized);
        }
    }
    unsafe fn raw_end_set_parameter(&self, _param: ParamPtr) {}
    fn get_state(&self) -> PluginState {
        unreachable!("the editor never reads the plugin state")
    }
    fn set_state(&self, _state: PluginState) {}
    fn request_restart(&self) {}
}

/// A camera looking along +y (from the front), one voxel per 10 pixels, at the box centre.
fn front_camera() -> Camera {
    Camera {
        yaw: 0.0,
        pitch: 0.0,
        pixels_per_voxel: 10.0,
        target: [BOX_SIDE as f32 / 2.0; 3],
        section: None,
    }
}

mod files;
mod recordings;
mod sculpting;
mod tuning;
mod view;
mod window;
