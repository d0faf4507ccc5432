//! The 3D view: picking, sections, zoom, the hit marker and the painted picture. Truths: the
//! geometry of an orthographic camera looking straight at a face, and projection/picking round
//! trips.

use super::*;
#[test]
fn a_click_straight_at_a_face_picks_that_face() {
    // Front camera: screen x = world x, screen up = world z, looking along +y. The ray through
    // the view's centre (16, *, 16) meets the 4-block [14,18]^3 on its front face y = 14, in
    // cell (16, 14, 16), normal -y; 15 pixels right and 5 up is x = 17.5, z = 16.5.
    let s = Sculptor::new(&block([4, 4, 4])).unwrap();
    let cam = front_camera();
    let p = view3d::pick(&s, &cam, [0.0, 0.0]).unwrap();
    assert_eq!(p.cell, [16, 14, 16]);
    assert_eq!(NORMALS[p.normal], [0, -1, 0]);
    assert!((p.point[1] - 14.0).abs() < 1e-3);
    let p = view3d::pick(&s, &cam, [15.0, -5.0]).unwrap();
    assert_eq!(p.cell, [17, 14, 16]);
    assert!((p.point[0] - 17.5).abs() < 1e-3 && (p.point[2] - 16.5).abs() < 1e-3);
    // Outside the block's silhouette: nothing.
    assert!(view3d::pick(&s, &cam, [25.0, 0.0]).is_none());
    // From straight above (elevation 89.9 degrees) the top face z = 18.
    let top = Camera {
        pitch: 1.5691,
        ..cam
    };
    let p = view3d::pick(&s, &top, [0.0, 0.0]).unwrap();
    assert_eq!(NORMALS[p.normal], [0, 0, 1]);
    assert_eq!(p.cell[2], 17);
}

#[test]
fn every_visible_face_picks_back_to_itself() {
    // Round trip: project the centre of each face the view draws (nearest last), click there,
    // and the pick is that face. Faces hidden behind nearer ones are skipped by checking that
    // the face is the nearest one drawn at that pixel.
    let mut s = Sculptor::new(&Sculpt::default()).unwrap();
    s.load_primitive("bowl:d=16,wall=2", 12).unwrap();
    let cam = Camera {
        target: [16.0; 3],
        pixels_per_voxel: 12.0,
        ..Camera::default()
    };
    let faces = view3d::visible_faces(&s, &cam);
    assert!(faces.len() > 100);
    // Farthest first.
    assert!(faces.windows(2).all(|w| w[0].depth >= w[1].depth));
    let mut checked = 0;
    for f in faces.iter().rev().step_by(7) {
        let centre = [0, 1, 2].map(|a| f.corners.iter().map(|p| p[a]).sum::<f32>() / 4.0);
        let (px, depth) = cam.project(centre);
        let p = view3d::pick(&s, &cam, px).unwrap();
        let picked_centre_depth = cam.project(p.point).1;
        if (picked_centre_depth - depth).abs() > 1e-2 {
            continue; // a nearer face covers this one's centre
        }
        assert_eq!((p.cell, p.normal), (f.cell, f.normal));
        checked += 1;
    }
    assert!(checked > 20, "{checked} faces checked");
}

#[test]
fn a_section_shows_the_inside_of_a_hollow_object() {
    // Truth: the geometry by hand. An 8^3 block hollowed with a 1-voxel wall spans cells
    // 12..20; from straight above, the centre ray meets its top (z = 20). Cut at z = 16 it
    // meets the cavity's floor instead (the top of the bottom wall, z = 13), and the cut
    // wall's rim faces show; a cut above the object changes nothing.
    let mut s = Sculptor::new(&block([8, 8, 8])).unwrap();
    s.hollow(1).unwrap();
    let mut cam = Camera {
        pitch: 1.5691,
        ..front_camera()
    };
    let top = view3d::pick(&s, &cam, [0.0, 0.0]).unwrap();
    assert_eq!((top.cell[2], NORMALS[top.normal]), (19, [0, 0, 1]));
    let whole = view3d::visible_faces(&s, &cam).len();
    cam.section = Some(view3d::Section { axis: 2, at: 16.0 });
    let floor = view3d::pick(&s, &cam, [0.0, 0.0]).unwrap();
    assert_eq!((floor.cell[2], NORMALS[floor.normal]), (12, [0, 0, 1]));
    assert!((floor.point[2] - 13.0).abs() < 1e-3);
    let cut = view3d::visible_faces(&s, &cam);
    assert!(cut
        .iter()
        .any(|f| f.cell[2] == 15 && NORMALS[f.normal] == [0, 0, 1]));
    assert_ne!(cut.len(), whole);
    cam.section = Some(view3d::Section { axis: 2, at: 25.0 });
    assert_eq!(view3d::visible_faces(&s, &cam).len(), whole);
}

#[test]
fn zooming_keeps_the_point_under_the_cursor() {
    // Truth: the projection itself. A world point under the cursor projects to the same
    // screen offset after zooming in or out there (to float rounding), and the scale changes
    // by the factor; zooming at the centre keeps the target.
    let mut cam = Camera::default();
    let cursor = [120.0, -45.0];
    let (o, d) = cam.ray(cursor);
    let under = [0, 1, 2].map(|a| o[a] + 64.0 * d[a]);
    for factor in [1.5, 0.5, 3.0] {
        let before = cam.pixels_per_voxel;
        cam.zoom_at(cursor, factor);
        assert!((cam.pixels_per_voxel / before - factor).abs() < 1e-5);
        let (p, _) = cam.project(under);
        assert!(
            (p[0] - cursor[0]).abs() < 1e-2 && (p[1] - cursor[1]).abs() < 1e-2,
            "{p:?}"
        );
    }
    let target = cam.target;
    cam.zoom_at([0.0, 0.0], 2.0);
    assert_eq!(cam.target, target);
}

#[test]
fn the_hit_marker_sits_where_the_strike_lands_and_hides_behind_the_object() {
    // Truth: the geometry by hand. A 10-voxel glass bowl (2-voxel wall) sits in the box with its
    // rim on top; Hit (0.5, 0.5, 0.9) aims near the rim height over the empty middle, which is
    // no surface: the marker lands on the nearest face (the inner wall or the floor, never in
    // the air), within a voxel of the object's filled cells, and pushes into it. Seen from
    // above (the default camera looks down) a point on the block's bottom is covered, its
    // top is not.
    let host = TestHost::default();
    let setter = ParamSetter { raw_context: &host };
    let mut app = app_with(Sculpt::from_spec("bowl:d=10,wall=2").unwrap());
    for (param, v) in app.params.strike.hit().into_iter().zip([0.5, 0.5, 0.9]) {
        setter.set_parameter(param, v);
    }
    let aim = app.hit_aim().unwrap();
    let m = app.hit_marker().unwrap();
    let cell = m.point.map(|v| v.floor() as i64);
    let near_solid = (-1..=1).any(|dx| {
        (-1..=1).any(|dy| {
            (-1..=1).any(|dz| app.sculptor.get([cell[0] + dx, cell[1] + dy, cell[2] + dz]))
        })
    });
    assert!(near_solid, "the marker {m:?} floats away from the bowl");
    assert!(
        !app.sculptor.get(aim.map(|v| v.floor() as i64)),
        "the aim is in the air"
    );
    let into: f32 = (0..3).map(|a| m.direction[a] * (m.point[a] - aim[a])).sum();
    assert!(into >= 0.0, "{m:?} pushes out of the bowl");
    // The block: top seen, bottom covered, from the default camera.
    let mut app = app_with(block([4, 4, 4]));
    let cam = Camera {
        target: [16.0; 3],
        ..Camera::default()
    };
    let top = app.hit_marker().unwrap();
    assert_eq!(top.direction, [0.0, 0.0, -1.0]);
    assert!(view3d::unoccluded(&app.sculptor, &cam, top.point));
    setter.set_parameter(&app.params.strike.hit_z, 0.0);
    let bottom = app.hit_marker().unwrap();
    assert!((bottom.point[2] - 14.0).abs() < 1e-6, "{bottom:?}");
    assert_eq!(bottom.direction, [0.0, 0.0, 1.0]);
    assert!(!view3d::unoccluded(&app.sculptor, &cam, bottom.point));
    // "Force Normal to Surface" off: the marker's direction is the azimuth and elevation's.
    setter.set_parameter(&app.params.strike.force_normal, false);
    setter.set_parameter(&app.params.strike.force_elevation, -90.0);
    let d = app.hit_marker().unwrap().direction;
    assert!(d[2] < -0.999, "{d:?}");
}

#[test]
fn partial_voxels_are_drawn_as_their_filled_volume() {
    // The default bowl keeps its cut voxels: each is drawn as a box of exactly its filled
    // volume (to f32 rounding), inside its own cell, so the view shows the smooth surface.
    let s = Sculptor::new(&Sculpt::default()).unwrap();
    let n = s.side() as i64;
    let mut partial = 0;
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let fill = s.fill([x, y, z]);
                let VoxelFill::Partial(sub) = fill else {
                    continue;
                };
                let (lo, hi) = view3d::cell_box(&fill);
                let volume: f32 = (0..3).map(|a| hi[a] - lo[a]).product();
                assert!((volume as f64 - sub.mean()).abs() < 1e-5, "{volume}");
                assert!((0..3).all(|a| lo[a] >= 0.0 && hi[a] <= 1.0 + 1e-6));
                partial += 1;
            }
        }
    }
    assert!(partial > 100, "{partial} partial voxels");
}

#[test]
fn the_view_paints_what_a_ray_sees_at_every_angle() {
    // Truth: the ray through each pixel's centre (`view3d::pick`, a voxel walk that knows
    // nothing of the painter's order) names the cell the eye sees there. The view paints the
    // faces of `visible_faces` back to front as triangles; rasterising them here in that
    // order (the last triangle covering a pixel centre wins) must give the same cell at every
    // pixel: no gap (a pixel left empty inside the object), no see-through (a farther cell on
    // top). Pixel centres exactly on a shared edge can go either way: 0.3 % of the object's
    // pixels allows for them. Shapes: the default bowl (partial voxels, curved), a hollow box
    // cut open by a section (inside faces), and an L of full voxels; 24 view angles each.
    let mut bowl = Sculptor::new(&Sculpt::default()).unwrap();
    bowl.load_primitive("bowl:d=16,wall=2", 16).unwrap();
    let mut hollow = Sculptor::new(&Sculpt::default()).unwrap();
    hollow.load_primitive("box:10x10x10,hollow=2", 10).unwrap();
    let l_shape = Sculptor::new(&Sculpt::from_grid(
        &modalforge::shape::VoxelGrid::from_fn([8, 6, 5], 1.0, |x, y, _| x < 3.0 || y < 2.0)
            .unwrap(),
    ))
    .unwrap();
    let size = [160usize, 120];
    for (name, sculptor, section) in [
        ("bowl", &bowl, None),
        (
            "hollow box, cut",
            &hollow,
            Some(view3d::Section { axis: 1, at: 16.0 }),
        ),
        ("L", &l_shape, None),
    ] {
        for yaw in [-2.8f32, -1.7, -0.6, 0.4, 1.3, 2.4] {
            for pitch in [-1.2f32, -0.3, 0.55, 1.45] {
                let mut cam = Camera {
                    yaw,
                    pitch,
                    section,
                    ..Camera::default()
                };
                cam.frame(sculptor, [size[0] as f32, size[1] as f32]);
                let faces = view3d::visible_faces(sculptor, &cam);
                let mut painted: Vec<Option<[i64; 3]>> = vec![None; size[0] * size[1]];
                let offset = |i: usize, j: usize| {
                    [
                        i as f32 + 0.5 - size[0] as f32 / 2.0,
                        j as f32 + 0.5 - size[1] as f32 / 2.0,
                    ]
                };
                for face in &faces {
                    let p = face.corners.map(|c| cam.project(c).0);
                    for tri in [[p[0], p[1], p[2]], [p[0], p[2], p[3]]] {
                        let lo = [0, 1].map(|a| tri.iter().map(|v| v[a]).fold(f32::MAX, f32::min));
                        let hi = [0, 1].map(|a| tri.iter().map(|v| v[a]).fold(f32::MIN, f32::max));
                        let range = |a: usize| {
                            let half = size[a] as f32 / 2.0;
                            let first = (lo[a] + half - 0.5).ceil().max(0.0) as usize;
                            let last =
                                ((hi[a] + half - 0.5).floor() as i64).min(size[a] as i64 - 1);
                            first..(last + 1).max(first as i64) as usize
                        };
                        let edge = |a: [f32; 2], b: [f32; 2], q: [f32; 2]| {
                            (b[0] - a[0]) * (q[1] - a[1]) - (b[1] - a[1]) * (q[0] - a[0])
                        };
                        for j in range(1) {
                            for i in range(0) {
                                let q = offset(i, j);
                                let e = [
                                    edge(tri[0], tri[1], q),
                                    edge(tri[1], tri[2], q),
                                    edge(tri[2], tri[0], q),
                                ];
                                if e.iter().all(|&v| v >= 0.0) || e.iter().all(|&v| v <= 0.0) {
                                    painted[j * size[0] + i] = Some(face.cell);
                                }
                            }
                        }
                    }
                }
                let (mut object, mut wrong) = (0, 0);
                for j in 0..size[1] {
                    for i in 0..size[0] {
                        let seen = view3d::pick(sculptor, &cam, offset(i, j)).map(|p| p.cell);
                        let drawn = painted[j * size[0] + i];
                        object += usize::from(seen.is_some() || drawn.is_some());
                        wrong += usize::from(seen != drawn);
                    }
                }
                assert!(
                    object > 1000,
                    "{name} at yaw {yaw}, pitch {pitch}: {object} pixels"
                );
                assert!(
                    wrong as f64 <= 0.003 * object as f64,
                    "{name} at yaw {yaw}, pitch {pitch}: {wrong} of {object} pixels differ"
                );
            }
        }
    }
}
