//! Per-texel (lightmap) bakes against a closed form: the shadowed transfer's DC coefficient
//! under a rectangle is `(√π/2)(1 − F)`, with `F` the form factor from the texel's surface
//! point to the rectangle (parallel-rectangle form factor, summed over corner rectangles).

use glam::{DVec3, Vec3};
use prt_bake::{bake, BakeError, BakeSettings, PointKind};
use prt_bakefile::{SampleKind, TransferKind};
use prt_scene::{Camera, Environment, Material, Mesh, Scene};
use prt_tracer::Accel;

/// A square `[lo, hi]²` at height `y`, facing `+Y` (`up`) or `−Y`, optionally with UVs
/// `((x − lo)/(hi − lo), (z − lo)/(hi − lo))`.
fn square(lo: f32, hi: f32, y: f32, up: bool, uvs: bool) -> Mesh {
    let p = [[lo, y, lo], [hi, y, lo], [hi, y, hi], [lo, y, hi]];
    let n = if up { Vec3::Y } else { -Vec3::Y };
    // Counter-clockwise seen from the side the normal points to.
    let indices = if up {
        vec![[0, 2, 1], [0, 3, 2]]
    } else {
        vec![[0, 1, 2], [0, 2, 3]]
    };
    Mesh {
        name: if up { "floor".into() } else { "blocker".into() },
        positions: p.iter().map(|v| Vec3::from_array(*v)).collect(),
        normals: vec![n; 4],
        indices,
        material: 0,
        texcoords: if uvs {
            vec![p
                .iter()
                .map(|v| [(v[0] - lo) / (hi - lo), (v[2] - lo) / (hi - lo)])
                .collect()]
        } else {
            Vec::new()
        },
        colors: Vec::new(),
    }
}

fn scene(meshes: Vec<Mesh>) -> Scene {
    let cam = Camera::look_at(DVec3::new(0.0, 2.0, 3.0), DVec3::ZERO, 40.0, 16, 12);
    let mut s = Scene::new(cam, Environment::uniform([1.0; 3]));
    let m = s.add_material("grey", Material::Lambert { albedo: [0.5; 3] });
    for mesh in meshes {
        s.add_mesh(mesh, m);
    }
    s
}

fn settings(size: u32, rays: u32) -> BakeSettings {
    BakeSettings {
        order: Some(2),
        rays,
        bounces: 0,
        points: PointKind::Texel {
            width: size,
            height: size,
        },
        progress: false,
        ..BakeSettings::default()
    }
}

/// Form factor from a differential area (normal toward the rectangle) to the parallel
/// rectangle `[0, a] × [0, b]` at distance `c` whose corner lies on its normal (signed: a
/// negative side flips the sign, so that corner rectangles add up).
fn corner(a: f64, b: f64, c: f64) -> f64 {
    let (x, y) = (a.abs() / c, b.abs() / c);
    let (sx, sy) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
    let f = (x / sx * (y / sx).atan() + y / sy * (x / sy).atan()) / (2.0 * std::f64::consts::PI);
    a.signum() * b.signum() * f
}

/// Form factor from `(px, pz)` on the floor to the rectangle `[x0, x1] × [z0, z1]` at height c.
fn form_factor(px: f64, pz: f64, x0: f64, x1: f64, z0: f64, z1: f64, c: f64) -> f64 {
    corner(x1 - px, z1 - pz, c) - corner(x0 - px, z1 - pz, c) - corner(x1 - px, z0 - pz, c)
        + corner(x0 - px, z0 - pz, c)
}

#[test]
fn texel_transfer_under_a_rectangle_matches_the_form_factor() {
    // A 2×2 floor lightmapped at 32×32, a 1×1 blocker 0.3 above its centre (no UVs:
    // lightmapped through a generated atlas in the same file).
    let (size, rays, c) = (32u32, 1024u32, 0.3f64);
    let s = scene(vec![
        square(-1.0, 1.0, 0.0, true, true),
        square(-0.5, 0.5, c as f32, false, false),
    ]);
    let accel = Accel::build(&s).unwrap();
    let out = bake(&s, &accel, &settings(size, rays)).unwrap();
    let b = &out.bake;
    assert_eq!(
        b.meta.sample_kind,
        SampleKind::Texel {
            width: size,
            height: size
        }
    );
    let (floor, blocker) = (&b.objects[0], &b.objects[1]);
    // The blocker has no UVs: one chart of a generated atlas, at a density of about
    // `size − 2` texels per unit (a 2-texel gutter), so at least `(size − 3)²` texels.
    assert_eq!(blocker.point_count, u64::from(size * size));
    let bc = blocker
        .coverage
        .as_ref()
        .expect("the blocker's atlas coverage");
    let n = bc.hits.iter().filter(|&&h| h == 1).count();
    assert!(n >= ((size - 3) * (size - 3)) as usize, "{n}");
    let cov = floor.coverage.as_ref().expect("texel coverage");
    assert_eq!(floor.point_count, u64::from(size * size));
    assert!(cov.hits.iter().all(|&h| h == 1), "every texel covered");
    let block = floor
        .blocks
        .iter()
        .find(|b| b.kind == TransferKind::ShadowedDiffuse)
        .unwrap();
    let lm = prt_scene::lightmap::lightmap(&s.meshes[0], size, size).unwrap();
    // Per texel: the fraction p = 1 − F of cosine-weighted rays that escape is estimated from
    // `rays` rays; as independent draws its standard error is √(p(1−p)/N) (the R2 sequence
    // does better). Allow 5 of those per texel (over 1024 texels a chance below 1e-3 for
    // random draws), and for the mean over texels 5 of those over √texels.
    let dc = std::f64::consts::PI.sqrt() / 2.0;
    let (mut sum_err, mut sum_sigma, mut sum_z2) = (0.0, 0.0, 0.0);
    for (k, t) in lm.texels.iter().enumerate() {
        let t = t.unwrap();
        let (px, pz) = (f64::from(t.position.x), f64::from(t.position.z));
        let p = 1.0 - form_factor(px, pz, -0.5, 0.5, -0.5, 0.5, c);
        let want = dc * p;
        let got = f64::from(block.data[k * 4]);
        let sigma = dc
            * (p * (1.0 - p) / f64::from(rays))
                .sqrt()
                .max(1.0 / f64::from(rays));
        assert!(
            (got - want).abs() <= 5.0 * sigma,
            "texel {k} at ({px:.3}, {pz:.3}): T00 {got:.5}, closed form {want:.5} (σ {sigma:.5})"
        );
        sum_err += got - want;
        sum_sigma += sigma;
        sum_z2 += ((got - want) / sigma).powi(2);
    }
    let n = lm.texels.len() as f64;
    // Squared errors in units of σ: their mean is 1 for independent draws (χ² with one degree
    // of freedom per texel, standard deviation √(2/n) of the mean), lower for the R2 sequence
    // (0.05 measured). Texel points half a texel off the UV mapping raise it to 1.7, a sixth
    // of a texel to 0.23: the tolerance 1 + 5√(2/n) catches a misplaced lightmap that the
    // per-texel bound alone lets through.
    let mean_z2 = sum_z2 / n;
    assert!(
        mean_z2 <= 1.0 + 5.0 * (2.0 / n).sqrt(),
        "mean squared error {mean_z2:.3} σ²"
    );
    let mean_sigma = sum_sigma / n / n.sqrt();
    assert!(
        (sum_err / n).abs() <= 5.0 * mean_sigma,
        "mean error {:.2e} (σ of the mean {mean_sigma:.2e})",
        sum_err / n
    );
    // The shadow is there: the texel under the blocker's centre sees F ≈ 0.48.
    let centre = (size / 2) * size + size / 2;
    assert!(f64::from(block.data[centre as usize * 4]) < 0.6 * dc);
}

#[test]
fn lightmap_problems_are_errors_naming_the_object() {
    // UVs beyond the unit square.
    let mut floor = square(-1.0, 1.0, 0.0, true, true);
    floor.texcoords[0][2] = [1.5, 1.0];
    let s = scene(vec![floor]);
    let accel = Accel::build(&s).unwrap();
    let e = bake(&s, &accel, &settings(16, 16)).unwrap_err();
    assert!(matches!(e, BakeError::Lightmap { ref object, .. } if object == "floor"));
    let msg = e.to_string();
    assert!(
        msg.contains("1 of 4 lightmap UVs") && msg.contains("0.5"),
        "{msg}"
    );
    // No object with UVs, and an atlas that cannot fit: a 2×2 map holds no chart with its
    // 2-texel gutter.
    let s = scene(vec![square(-1.0, 1.0, 0.0, true, false)]);
    let accel = Accel::build(&s).unwrap();
    let e = bake(&s, &accel, &settings(2, 16)).unwrap_err();
    assert!(
        e.to_string().contains("no object could be lightmapped"),
        "{e}"
    );
    // An impossible size.
    let s = scene(vec![square(-1.0, 1.0, 0.0, true, true)]);
    let accel = Accel::build(&s).unwrap();
    for size in [0, prt_scene::lightmap::MAX_LIGHTMAP_SIZE + 1] {
        let e = bake(&s, &accel, &settings(size, 16)).unwrap_err();
        assert!(e.to_string().contains("lightmap of"), "{e}");
    }
}

#[test]
fn texel_bakes_are_identical_on_any_thread_count() {
    let s = scene(vec![
        square(-1.0, 1.0, 0.0, true, true),
        square(-0.5, 0.5, 0.3, false, false),
    ]);
    let accel = Accel::build(&s).unwrap();
    let mut st = settings(16, 64);
    st.bounces = 1;
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| bake(&s, &accel, &st).unwrap().bake)
    };
    let (a, b) = (run(1), run(3));
    for (x, y) in a.objects.iter().zip(&b.objects) {
        for (bx, by) in x.blocks.iter().zip(&y.blocks) {
            assert_eq!(bx.kind, by.kind);
            assert!(bx
                .data
                .iter()
                .zip(&by.data)
                .all(|(p, q)| p.to_bits() == q.to_bits()));
        }
    }
    // One bounce: 3 channels, interreflected.
    assert_eq!(a.objects[0].channels, 3);
}
