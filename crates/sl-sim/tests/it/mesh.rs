//! Triangle-mesh scenes: an icosphere against the analytic sphere it approximates.

use std::collections::HashMap;

use nalgebra::{Isometry3, Point2, Point3, Vector3};
use proptest::prelude::*;
use sl_camera::{ImageSize, Intrinsics};
use sl_sim::{NO_OBJECT, RigConfig, Scene, SceneObject, Shape, Texture, VirtualRig};

/// An icosphere of radius `r` centred on the origin: an icosahedron whose faces are split in
/// four `levels` times, every vertex pushed onto the sphere.
fn icosphere(r: f64, levels: u32) -> (Vec<Point3<f64>>, Vec<[u32; 3]>) {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut v: Vec<Vector3<f64>> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vector3::new(x, y, z).normalize())
    .collect();
    let mut f: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut next = Vec::with_capacity(f.len() * 4);
        for [a, b, c] in f {
            let mut m = |i: u32, j: u32| {
                *mid.entry((i.min(j), i.max(j))).or_insert_with(|| {
                    v.push((v[i as usize] + v[j as usize]).normalize());
                    (v.len() - 1) as u32
                })
            };
            let (ab, bc, ca) = (m(a, b), m(b, c), m(c, a));
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        f = next;
    }
    (v.into_iter().map(|p| Point3::from(p * r)).collect(), f)
}

fn small_rig(scale: f64) -> RigConfig {
    let mut c = RigConfig::default();
    let k = c.camera.intrinsics;
    c.camera.intrinsics = Intrinsics::new(
        k.fx / scale,
        k.fy / scale,
        (k.cx + 0.5) / scale - 0.5,
        (k.cy + 0.5) / scale - 0.5,
    );
    c.camera.size = ImageSize::new((1280.0 / scale) as u32, (720.0 / scale) as u32);
    c
}

#[test]
fn icosphere_lies_between_its_inscribed_and_circumscribed_spheres() {
    let r = 50.0;
    let (v, f) = icosphere(r, 4);
    // Inner radius: the smallest distance from the centre to a face plane (closed form per
    // face, independent of the ray caster).
    let r_in = f
        .iter()
        .map(|&[a, b, c]| {
            let (a, b, c) = (v[a as usize], v[b as usize], v[c as usize]);
            let n = (b - a).cross(&(c - a)).normalize();
            n.dot(&a.coords).abs()
        })
        .fold(f64::INFINITY, f64::min);
    assert!(r_in > 0.99 * r && r_in < r);
    let centre = Isometry3::translation(0.0, 0.0, 450.0);
    let config = small_rig(4.0);
    let mesh = Shape::mesh("icosphere", v, f).unwrap();
    let mesh_rig = VirtualRig::new(
        config.clone(),
        Scene::new().with(SceneObject::in_camera(
            "icosphere",
            mesh,
            Texture::Uniform(0.5),
            centre,
        )),
    )
    .unwrap();
    let ball_rig = mesh_rig
        .with_scene(Scene::new().with(SceneObject::in_camera(
            "sphere",
            Shape::Sphere { radius: r },
            Texture::Uniform(0.5),
            centre,
        )))
        .unwrap();
    let tm = mesh_rig.view(0.0, 0).unwrap().truth;
    let ts = ball_rig.view(0.0, 0).unwrap().truth;
    let c = Point3::new(0.0, 0.0, 450.0);
    let (mut both, mut max_gap) = (0, 0.0f64);
    for i in 0..tm.object.len() {
        if tm.object[i] == NO_OBJECT || ts.object[i] == NO_OBJECT {
            continue;
        }
        both += 1;
        let d = (tm.points_cam[i] - c).norm();
        // 1e-9 mm: rounding of parry's ray–triangle test at 450 mm.
        assert!(
            d >= r_in - 1e-9 && d <= r + 1e-9,
            "pixel {i}: {d} not in [{r_in}, {r}]"
        );
        // The mesh is inside the sphere: seen from outside, it is never nearer.
        assert!(tm.depth_mm[i] >= ts.depth_mm[i] - 1e-9);
        max_gap = max_gap.max(tm.depth_mm[i] - ts.depth_mm[i]);
    }
    assert!(both > 3000);
    // Along a ray the gap can exceed r - r_in only near the silhouette.
    assert!(max_gap > 0.0);
    // The mesh object is reported with its name, on the right pose.
    assert_eq!(tm.objects[0].name, "icosphere");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 16, ..ProptestConfig::default() })]

    /// Law: wherever the truth says a pixel sees a lit plane, its projector coordinate is the
    /// projection through the projector model of the ray–plane intersection, for any plane
    /// pose in front of the rig.
    #[test]
    fn plane_truth_is_the_ray_plane_projection(
        tx in -50.0f64..50.0, ty in -50.0f64..50.0, tz in 380.0f64..550.0,
        ax in -0.6f64..0.6, ay in -0.6f64..0.6,
    ) {
        let config = small_rig(8.0);
        let pose = Isometry3::new(Vector3::new(tx, ty, tz), Vector3::new(ax, ay, 0.0));
        let rig = VirtualRig::new(
            config.clone(),
            Scene::new().with(SceneObject::in_camera("p", Shape::rectangle(3000.0, 3000.0), Texture::Uniform(0.7), pose)),
        ).unwrap();
        let t = rig.view(0.0, 0).unwrap().truth;
        let n = pose.rotation * Vector3::z();
        let t_proj_cam = config.t_cam_proj.inverse();
        for y in 0..t.height {
            for x in 0..t.width {
                let i = (y * t.width + x) as usize;
                let d = config.camera.unproject(&Point2::new(f64::from(x), f64::from(y))).unwrap();
                let p = Point3::from(d * (n.dot(&pose.translation.vector) / n.dot(&d)));
                let q = config.projector.project(&(t_proj_cam * p)).filter(|q| config.projector.size.contains(q.x, q.y));
                prop_assert_eq!(t.lit(i), q.is_some());
                if let Some(q) = q {
                    prop_assert!((t.projector[i] - q).norm() < 1e-6);
                }
            }
        }
    }
}

#[test]
fn stanford_bunny_stands_on_the_table() {
    let Some(root) = std::env::var_os("SL_DATA") else {
        eprintln!("SL_DATA not set: skipping the Stanford bunny scene");
        return;
    };
    let path = std::path::Path::new(&root).join("bunny").join("bun000.ply");
    let scene = Scene::ply_mesh(&path, sl_sim::MeshUnits::Auto, Vector3::y()).unwrap();
    let Shape::Mesh(mesh) = &scene.objects[0].shape else {
        panic!("a mesh expected")
    };
    let (mut lo, mut hi) = (
        Vector3::repeat(f64::INFINITY),
        Vector3::repeat(f64::NEG_INFINITY),
    );
    for v in mesh.vertices() {
        lo = lo.inf(&v.coords);
        hi = hi.sup(&v.coords);
    }
    // Detected as metres; resting on the table (lowest point at z = 0), centred on the axis;
    // the bunny is about 15 cm tall (bun000 is a partial scan: 10–20 cm).
    assert!(lo.z.abs() < 1e-9);
    assert!((lo.x + hi.x).abs() < 1e-9 && (lo.y + hi.y).abs() < 1e-9);
    assert!(hi.z > 100.0 && hi.z < 200.0, "height {}", hi.z);
    let rig = VirtualRig::new(small_rig(4.0), scene).unwrap();
    let t = rig.view(0.0, 0).unwrap().truth;
    assert!(t.lit_count() > 2000, "{} lit pixels", t.lit_count());
}
