//! The editor's 3D view of the voxel object: an orbiting orthographic camera, the exposed
//! faces shaded and sorted back to front (painter's algorithm), and picking a clicked face by
//! walking the ray through the grid (Amanatides & Woo's voxel traversal).
//!
//! Where it sits: between the window (pixels) and [`super::sculptor::Sculptor`] (cells). Pure
//! geometry, no egui types, so picking is tested without a window.

use super::sculptor::Sculptor;
use modalforge::shape::VoxelFill;

/// A 3D vector.
pub type V3 = [f32; 3];

fn dot(a: V3, b: V3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The six face normals, as cell offsets.
pub const NORMALS: [[i64; 3]; 6] = [
    [-1, 0, 0],
    [1, 0, 0],
    [0, -1, 0],
    [0, 1, 0],
    [0, 0, -1],
    [0, 0, 1],
];

/// An orbiting orthographic camera looking at `target` (world units: voxels, z up).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Rotation about the vertical axis, radians.
    pub yaw: f32,
    /// Elevation above the horizontal, radians (positive: looking down).
    pub pitch: f32,
    /// Pixels per voxel.
    pub pixels_per_voxel: f32,
    /// The point at the view's centre.
    pub target: V3,
    /// A section plane cutting part of the object away, so that its inside shows.
    pub section: Option<Section>,
}

/// A section plane: the view shows (and picks) only the cells whose centre lies below `at`
/// along `axis`; the part above is cut away.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Section {
    /// 0, 1, 2: x, y, z.
    pub axis: usize,
    /// Where the plane cuts, world units (voxels).
    pub at: f32,
}

impl Camera {
    /// What cell `c` holds as the view shows it: empty where the section cuts it away.
    pub fn shown(&self, sculptor: &Sculptor, c: [i64; 3]) -> VoxelFill {
        match self.section {
            Some(s) if c[s.axis] as f32 + 0.5 > s.at => VoxelFill::Empty,
            _ => sculptor.fill(c),
        }
    }
}

impl Default for Camera {
    fn default() -> Self {
        Self {
            yaw: -0.6,
            pitch: 0.55,
            pixels_per_voxel: 10.0,
            target: [16.0; 3],
            section: None,
        }
    }
}

impl Camera {
    /// Screen right, screen up and the viewing direction (into the screen), in world axes.
    pub fn basis(&self) -> (V3, V3, V3) {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        let right = [cy, sy, 0.0];
        let forward = [-sy * cp, cy * cp, -sp];
        let up = cross(right, forward);
        (right, up, forward)
    }

    /// Screen offset from the view's centre in pixels (y down) and depth (larger is farther).
    pub fn project(&self, p: V3) -> ([f32; 2], f32) {
        let (r, u, f) = self.basis();
        let d = [0, 1, 2].map(|a| p[a] - self.target[a]);
        (
            [
                dot(d, r) * self.pixels_per_voxel,
                -dot(d, u) * self.pixels_per_voxel,
            ],
            dot(d, f),
        )
    }

    /// The ray through a screen offset (pixels from the centre, y down): origin well in front
    /// of the object and the viewing direction.
    pub fn ray(&self, offset: [f32; 2]) -> (V3, V3) {
        let (r, u, f) = self.basis();
        let (sx, sy) = (
            offset[0] / self.pixels_per_voxel,
            -offset[1] / self.pixels_per_voxel,
        );
        let back = 4.0 * super::sculptor::BOX_SIDE as f32;
        let o = [0, 1, 2].map(|a| self.target[a] + sx * r[a] + sy * u[a] - back * f[a]);
        (o, f)
    }

    /// Zooms by `factor` towards a screen offset (pixels from the centre, y down): the point
    /// under the cursor stays under it (the scale is kept within 1-200 pixels per voxel).
    pub fn zoom_at(&mut self, offset: [f32; 2], factor: f32) {
        let before = self.pixels_per_voxel;
        self.pixels_per_voxel = (before * factor).clamp(1.0, 200.0);
        // The view-plane point under the cursor is target + (x r - y u) / scale: keep it.
        let k = 1.0 / before - 1.0 / self.pixels_per_voxel;
        let (r, u, _) = self.basis();
        self.target = [0, 1, 2].map(|a| self.target[a] + k * (offset[0] * r[a] - offset[1] * u[a]));
    }

    /// Rotates by a mouse drag (pixels), keeping the elevation within +-89 degrees.
    pub fn orbit(&mut self, drag: [f32; 2]) {
        self.yaw -= drag[0] * 0.01;
        self.pitch = (self.pitch + drag[1] * 0.01).clamp(-1.55, 1.55);
    }

    /// Frames the solid voxels in a view of `size_px` pixels.
    pub fn frame(&mut self, sculptor: &Sculptor, size_px: [f32; 2]) {
        if let Some((lo, dims)) = sculptor.bounds() {
            self.target = [0, 1, 2].map(|a| lo[a] as f32 + dims[a] as f32 / 2.0);
            let diag = dims.iter().map(|&d| (d * d) as f32).sum::<f32>().sqrt();
            self.pixels_per_voxel = 0.85 * size_px[0].min(size_px[1]) / diag.max(4.0);
        }
    }
}

/// One visible face: its cell, outward normal index into [`NORMALS`], four corners and the
/// depth of its cell's centre. Equal cubes on a grid seen orthographically are painted
/// correctly back to front by their centres' depth (a nearer cube can never be overlapped by a
/// farther one), which face centres would not guarantee.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Face {
    /// The solid cell it belongs to.
    pub cell: [i64; 3],
    /// Index into [`NORMALS`].
    pub normal: usize,
    /// Corners in world units, counter-clockwise seen from outside.
    pub corners: [V3; 4],
    /// Depth of the cell's centre (for sorting).
    pub depth: f32,
}

/// The exposed faces turned towards the camera, farthest first (of the cells the section
/// keeps, [`Camera::shown`]: a cut shows the inside). A partial voxel is drawn as
/// a smaller box of its filled volume, placed at its fill's centroid ([`cell_box`]); a full
/// voxel's face towards a partial neighbour stays visible.
pub fn visible_faces(sculptor: &Sculptor, camera: &Camera) -> Vec<Face> {
    let (_, _, f) = camera.basis();
    let n = sculptor.side() as i64;
    let mut faces = Vec::new();
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let c = [x, y, z];
                let fill = camera.shown(sculptor, c);
                if fill == VoxelFill::Empty {
                    continue;
                }
                let bx = cell_box(&fill);
                let centre = c.map(|v| v as f32 + 0.5);
                let cell_depth = camera.project(centre).1;
                for (k, d) in NORMALS.iter().enumerate() {
                    let nf = d.map(|v| v as f32);
                    let neighbour = camera.shown(sculptor, [x + d[0], y + d[1], z + d[2]]);
                    let hidden = neighbour == VoxelFill::Full && fill == VoxelFill::Full;
                    if dot(nf, f) >= 0.0 || hidden {
                        continue;
                    }
                    faces.push(Face {
                        cell: c,
                        normal: k,
                        corners: face_corners(c, k, bx),
                        depth: cell_depth,
                    });
                }
            }
        }
    }
    faces.sort_by(|a, b| b.depth.total_cmp(&a.depth));
    faces
}

/// The box a voxel is drawn as, in cell units (`lo`, `hi` per axis within `[0, 1]`): the
/// whole cell when full; for a partial voxel a cube of its filled volume centred on its fill's
/// centroid, kept inside the cell.
pub fn cell_box(fill: &VoxelFill) -> ([f32; 3], [f32; 3]) {
    match fill {
        VoxelFill::Partial(sub) => {
            let side = sub.mean().cbrt() as f32;
            let centroid = sub.centroid_offset();
            let lo =
                [0, 1, 2].map(|a| (0.5 + centroid[a] as f32 - side / 2.0).clamp(0.0, 1.0 - side));
            (lo, [0, 1, 2].map(|a| lo[a] + side))
        }
        _ => ([0.0; 3], [1.0; 3]),
    }
}

/// Where the ray `o + t d` enters the box `lo..hi` (slab test): `t` and the axis of the face it
/// enters through; `None` if it misses.
fn ray_box(o: V3, d: V3, lo: V3, hi: V3) -> Option<(f32, usize)> {
    let (mut t0, mut t1, mut axis) = (f32::NEG_INFINITY, f32::INFINITY, 0);
    for a in 0..3 {
        if d[a].abs() < 1e-12 {
            if o[a] < lo[a] || o[a] > hi[a] {
                return None;
            }
            continue;
        }
        let (ta, tb) = ((lo[a] - o[a]) / d[a], (hi[a] - o[a]) / d[a]);
        if ta.min(tb) > t0 {
            t0 = ta.min(tb);
            axis = a;
        }
        t1 = t1.min(ta.max(tb));
    }
    (t0 <= t1).then_some((t0, axis))
}

/// The four corners of face `k` of cell `c` drawn as the box `bx` ([`cell_box`]).
fn face_corners(c: [i64; 3], k: usize, bx: ([f32; 3], [f32; 3])) -> [V3; 4] {
    let (lo, hi) = bx;
    let axis = k / 2;
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let mut base = [0, 1, 2].map(|a| c[a] as f32 + lo[a]);
    if k % 2 == 1 {
        base[axis] = c[axis] as f32 + hi[axis];
    }
    let (su, sv) = (hi[u] - lo[u], hi[v] - lo[v]);
    let at = |du: f32, dv: f32| {
        let mut p = base;
        p[u] += du * su;
        p[v] += dv * sv;
        p
    };
    [at(0.0, 0.0), at(1.0, 0.0), at(1.0, 1.0), at(0.0, 1.0)]
}

/// Shade of a face with normal `k` under a light from the viewer's upper left, 0..1.
pub fn shade(camera: &Camera, k: usize) -> f32 {
    let (r, u, f) = camera.basis();
    let light = [0, 1, 2].map(|a| -0.45 * r[a] + 0.6 * u[a] - 0.65 * f[a]);
    let n = NORMALS[k].map(|v| v as f32);
    0.35 + 0.65 * dot(n, light).max(0.0)
}

/// Whether `point`, on the object's surface, is what the view sees along its line of sight (no
/// other part of the object in front of it). A tolerance of 3/4 voxel in depth: a point on a
/// partial voxel's face lies up to that far behind the box the view draws for it, and any
/// covering wall is at least a voxel thick.
pub fn unoccluded(sculptor: &Sculptor, camera: &Camera, point: V3) -> bool {
    let (offset, depth) = camera.project(point);
    pick(sculptor, camera, offset).is_none_or(|p| camera.project(p.point).1 >= depth - 0.75)
}

/// What a click hit: the solid cell, the face's normal index and the point on the face.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pick {
    /// The solid cell.
    pub cell: [i64; 3],
    /// Index into [`NORMALS`] of the face the ray entered through.
    pub normal: usize,
    /// Where the ray meets the face, world units.
    pub point: V3,
}

impl Pick {
    /// The empty cell in front of the face (where an added voxel goes).
    pub fn outside(&self) -> [i64; 3] {
        let d = NORMALS[self.normal];
        [0, 1, 2].map(|a| self.cell[a] + d[a])
    }
}

/// The first solid cell along the ray through a screen offset (pixels from the view's centre,
/// y down), by a voxel walk through the box.
pub fn pick(sculptor: &Sculptor, camera: &Camera, offset: [f32; 2]) -> Option<Pick> {
    let (o, d) = camera.ray(offset);
    let n = sculptor.side() as f32;
    // Clip the ray to the box [0, n]^3.
    let (mut t0, mut t1) = (0.0f32, f32::INFINITY);
    for a in 0..3 {
        if d[a].abs() < 1e-12 {
            if o[a] < 0.0 || o[a] > n {
                return None;
            }
            continue;
        }
        let (ta, tb) = ((0.0 - o[a]) / d[a], (n - o[a]) / d[a]);
        t0 = t0.max(ta.min(tb));
        t1 = t1.min(ta.max(tb));
    }
    if t0 > t1 {
        return None;
    }
    let t_in = t0 + 1e-4;
    let p = [0, 1, 2].map(|a| o[a] + t_in * d[a]);
    let mut cell = p.map(|v| (v.floor() as i64).clamp(0, n as i64 - 1));
    let step = d.map(|v| if v > 0.0 { 1i64 } else { -1 });
    let mut t_max = [0.0f32; 3];
    let mut t_delta = [f32::INFINITY; 3];
    for a in 0..3 {
        if d[a].abs() >= 1e-12 {
            let next = if step[a] > 0 {
                cell[a] as f32 + 1.0
            } else {
                cell[a] as f32
            };
            t_max[a] = (next - o[a]) / d[a];
            t_delta[a] = 1.0 / d[a].abs();
        } else {
            t_max[a] = f32::INFINITY;
        }
    }
    // The face the ray entered the box through.
    let mut entered = (0..3)
        .map(|a| {
            let ta = if d[a].abs() < 1e-12 {
                f32::NEG_INFINITY
            } else {
                ((if step[a] > 0 { 0.0 } else { n }) - o[a]) / d[a]
            };
            (ta, a)
        })
        .max_by(|x, y| x.0.total_cmp(&y.0))
        .map(|(_, a)| a)
        .unwrap_or(0);
    let mut t_enter = t0;
    loop {
        match camera.shown(sculptor, cell) {
            VoxelFill::Empty => {}
            VoxelFill::Full => {
                let normal = 2 * entered + usize::from(step[entered] < 0);
                let point = [0, 1, 2].map(|a| o[a] + t_enter * d[a]);
                return Some(Pick {
                    cell,
                    normal,
                    point,
                });
            }
            partial => {
                // A partial voxel is hit where its drawn box is.
                let (lo, hi) = cell_box(&partial);
                let lo = [0, 1, 2].map(|a| cell[a] as f32 + lo[a]);
                let hi = [0, 1, 2].map(|a| cell[a] as f32 + hi[a]);
                if let Some((t, axis)) = ray_box(o, d, lo, hi) {
                    return Some(Pick {
                        cell,
                        normal: 2 * axis + usize::from(step[axis] < 0),
                        point: [0, 1, 2].map(|a| o[a] + t * d[a]),
                    });
                }
            }
        }
        let a = (0..3)
            .min_by(|&x, &y| t_max[x].total_cmp(&t_max[y]))
            .unwrap_or(0);
        if t_max[a] > t1 {
            return None;
        }
        t_enter = t_max[a];
        cell[a] += step[a];
        if !(0..n as i64).contains(&cell[a]) {
            return None;
        }
        t_max[a] += t_delta[a];
        entered = a;
    }
}
