//! Per-vertex relit radiance from a bake against the path tracer at the same points, on a
//! non-convex mesh (the low-resolution Stanford bunny) under a real map (the courtyard).
//!
//! With the bake's transfer `T` (which excludes the receiver's albedo/π) and the map's exact
//! projection `L`, the relit radiance of a Lambert vertex is `(a/π) Σ_{i < n²} L_i T_i`; the path
//! tracer estimates `(a/π) ∫ L(ω) V(ω) max(0, n·ω) dω` (plus the interreflections) at the same
//! point. The difference has two parts: the SH truncation at order `n` (falls with `n`) and the
//! bake's Monte Carlo error (falls with rays), and the comparison adds the reference's own
//! noise, which we estimate from the spread of independent runs and report with every figure.
//!
//! - `study_error_per_order_and_rays` (ignored; `cargo test --release -p prt-bake --test
//!   against_path_tracer -- --ignored --nocapture`) prints the table of crates/bake/README.md.
//! - `bake_converges_to_path_tracer` is the CI version with tolerances derived from it.

use glam::{DMat4, DVec3};
use prt_bake::{bake, BakeOutput, BakeSettings};
use prt_bakefile::TransferKind;
use prt_scene::{Camera, Mapping, Material, Scene};
use prt_tracer::{Accel, RenderSettings, Renderer, SurfacePoint};
use std::f64::consts::PI;
use std::path::PathBuf;
use std::time::Instant;

const ALBEDO: f32 = 0.8;
/// Rays of the study's densest bake, which stands in for the bake's infinite-ray limit.
const DENSE_RAYS: u32 = 65536;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The low-resolution bunny scaled by 0.1 (about 1 unit tall), Lambert 0.8, under the
/// courtyard map: nothing else in the scene.
fn bunny_scene() -> Scene {
    let mesh = prt_scene::load_obj(
        &repo().join("scenes/meshes/bunny_lowres.obj"),
        &DMat4::from_scale(DVec3::splat(0.1)),
    )
    .expect("bunny_lowres.obj");
    let (env, _warnings) = prt_scene::load_environment(
        &repo().join("scenes/maps/courtyard.exr"),
        Mapping::LatLong,
        0.0,
        1.0,
    )
    .expect("courtyard.exr");
    let cam = Camera::look_at(
        DVec3::new(0.0, 0.5, 2.4),
        DVec3::new(0.0, 0.45, 0.0),
        40.0,
        16,
        12,
    );
    let mut scene = Scene::new(cam, env);
    let m = scene.add_material(
        "clay",
        Material::Lambert {
            albedo: [ALBEDO; 3],
        },
    );
    for mesh in mesh.meshes {
        scene.add_mesh(mesh, m);
    }
    scene
}

/// Relit RGB radiance of every vertex of object 0, keeping the first `order` bands only:
/// `(a/π) Σ_{i < order²} L_i T_i` per channel, `L` from `bake.environment.values`
/// (`[channel][coeff]`).
fn relit(out: &BakeOutput, order: usize) -> Vec<[f64; 3]> {
    let b = &out.bake;
    let obj = &b.objects[0];
    let env = b.environment.as_ref().expect("environment coefficients");
    let n2 = (obj.order * obj.order) as usize;
    let en2 = (env.order * env.order) as usize;
    assert!(order * order <= n2 && n2 <= en2);
    let k = order * order;
    let block = obj
        .blocks
        .iter()
        .find(|bl| {
            matches!(
                bl.kind,
                TransferKind::ShadowedDiffuse | TransferKind::InterreflectedDiffuse { .. }
            )
        })
        .expect("diffuse transfer block");
    let ch = obj.channels as usize;
    (0..obj.points_in_file as usize)
        .map(|p| {
            let mut rgb = [0.0; 3];
            for (c, out) in rgb.iter_mut().enumerate() {
                let t = &block.data[(p * ch + c.min(ch - 1)) * n2..][..k];
                let l = &env.values[c * en2..][..k];
                *out = f64::from(ALBEDO) / PI
                    * t.iter().zip(l).map(|(a, b)| f64::from(*a) * b).sum::<f64>();
            }
            rgb
        })
        .collect()
}

/// Path-traced radiance at the chosen vertices: the mean of `runs` independent runs (seeds
/// 1..=runs) of `spp` samples each, and the standard error of that mean per vertex and
/// channel, from the spread of the runs.
struct Reference {
    radiance: Vec<[f64; 3]>,
    std_error: Vec<[f64; 3]>,
}

fn reference(scene: &Scene, vertices: &[usize], bounces: u32, spp: u32, runs: u32) -> Reference {
    let mesh = &scene.meshes[0];
    let points: Vec<SurfacePoint> = vertices
        .iter()
        .map(|&v| SurfacePoint {
            position: mesh.positions[v],
            normal: mesh.normals[v],
            view_dir: mesh.normals[v],
            material: scene.materials[mesh.material],
        })
        .collect();
    let mut sum = vec![[0.0f64; 3]; points.len()];
    let mut sq = vec![[0.0f64; 3]; points.len()];
    for seed in 1..=u64::from(runs) {
        let rs = RenderSettings {
            spp,
            bounces: bounces as i32,
            seed,
            progress: false,
            ..Default::default()
        };
        let r = Renderer::new(scene, rs)
            .expect("renderer")
            .radiance_at_points(&points, spp)
            .expect("radiance at points");
        for ((s, q), l) in sum.iter_mut().zip(&mut sq).zip(&r) {
            for c in 0..3 {
                let x = f64::from(l[c]);
                s[c] += x;
                q[c] += x * x;
            }
        }
    }
    let k = f64::from(runs);
    let radiance: Vec<[f64; 3]> = sum.iter().map(|s| s.map(|x| x / k)).collect();
    let std_error = sum
        .iter()
        .zip(&sq)
        .map(|(s, q)| {
            let mut e = [0.0; 3];
            for c in 0..3 {
                let mean = s[c] / k;
                let var = ((q[c] / k - mean * mean) * k / (k - 1.0)).max(0.0);
                e[c] = (var / k).sqrt();
            }
            e
        })
        .collect();
    Reference {
        radiance,
        std_error,
    }
}

/// Relative RMS difference over the chosen vertices and channels,
/// `sqrt(Σ (bake − ref)² / Σ ref²)`.
fn rel_rms(bake: &[[f64; 3]], vertices: &[usize], reference: &Reference) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (&v, r) in vertices.iter().zip(&reference.radiance) {
        for c in 0..3 {
            num += (bake[v][c] - r[c]).powi(2);
            den += r[c] * r[c];
        }
    }
    (num / den).sqrt()
}

/// Relative RMS difference between two bakes' radiance, `sqrt(Σ (a − b)² / Σ ref²)` (all
/// vertices, normalised like [`rel_rms`]).
fn rel_diff(a: &[[f64; 3]], b: &[[f64; 3]], reference: &Reference) -> f64 {
    let num: f64 = a
        .iter()
        .zip(b)
        .flat_map(|(x, y)| (0..3).map(move |c| (x[c] - y[c]).powi(2)))
        .sum();
    let den: f64 = reference.radiance.iter().flatten().map(|r| r * r).sum();
    (num / den * reference.radiance.len() as f64 / a.len() as f64).sqrt()
}

/// The reference's own relative RMS noise `sqrt(Σ σ² / Σ ref²)`: the floor of [`rel_rms`].
fn noise(reference: &Reference) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (e, r) in reference.std_error.iter().zip(&reference.radiance) {
        for c in 0..3 {
            num += e[c] * e[c];
            den += r[c] * r[c];
        }
    }
    (num / den).sqrt()
}

/// Relative RMS truncation error of the *unshadowed* diffuse radiance at every vertex normal, per
/// order: the analytic rotated clamped cosine (`transfer::unshadowed`, bands from
/// `prt_sh::zonal::clamped_cosine_bands`) against the exact irradiance, summed over every texel
/// of the piecewise-constant map (texel-centre cosine times the texel's exact solid angle).
/// This is the part of the truncation error that is known in closed form; visibility adds
/// high frequencies, so the shadowed truncation error is larger.
fn unshadowed_truncation(scene: &Scene, orders: &[usize]) -> Vec<f64> {
    let img = &scene.environment.image;
    let (w, h) = (img.width, img.height);
    let mut dirs = Vec::with_capacity(w * h);
    for j in 0..h {
        let (t0, t1) = (PI * j as f64 / h as f64, PI * (j + 1) as f64 / h as f64);
        let omega = 2.0 * PI / w as f64 * (t0.cos() - t1.cos());
        let theta = PI * (j as f64 + 0.5) / h as f64;
        for i in 0..w {
            let phi = 2.0 * PI * (i as f64 + 0.5) / w as f64;
            let d = DVec3::new(
                phi.sin() * theta.sin(),
                theta.cos(),
                -phi.cos() * theta.sin(),
            );
            let t = img.texels[j * w + i];
            dirs.push((d, [0, 1, 2].map(|c| f64::from(t[c]) * omega)));
        }
    }
    let mesh = &scene.meshes[0];
    let exact: Vec<[f64; 3]> = mesh
        .normals
        .iter()
        .map(|n| {
            let n = n.normalize().as_dvec3();
            let mut e = [0.0; 3];
            for (d, l) in &dirs {
                let c = n.dot(*d);
                if c > 0.0 {
                    for k in 0..3 {
                        e[k] += l[k] * c;
                    }
                }
            }
            e
        })
        .collect();
    let max_order = orders.iter().copied().max().unwrap_or(1);
    let coeffs = prt_sh::project_env(
        prt_sh::ImageRef {
            width: w,
            height: h,
            texels: &img.texels,
        },
        prt_sh::EnvMapping::LatLong,
        max_order,
        0.0,
    )
    .unwrap();
    orders
        .iter()
        .map(|&o| {
            let (mut num, mut den) = (0.0, 0.0);
            for (n, e) in mesh.normals.iter().zip(&exact) {
                let u = prt_bake::transfer::unshadowed(o, n.normalize());
                for c in 0..3 {
                    let s: f64 = u.iter().zip(&coeffs).map(|(a, l)| a * l[c]).sum();
                    num += (s - e[c]).powi(2);
                    den += e[c] * e[c];
                }
            }
            (num / den).sqrt()
        })
        .collect()
}

fn settings(order: usize, rays: u32, bounces: u32) -> BakeSettings {
    BakeSettings {
        order: Some(order),
        rays,
        bounces,
        seed: 0,
        ..BakeSettings::final_quality()
    }
}

#[test]
#[ignore = "study: about 5 minutes in release; prints the tables of crates/bake/README.md"]
fn study_error_per_order_and_rays() {
    let scene = bunny_scene();
    let accel = Accel::build(&scene).unwrap();
    let n = scene.meshes[0].positions.len();
    let vertices: Vec<usize> = (0..n).collect();
    let orders = [2usize, 3, 4, 6, 8, 10, 12];
    let rays = [64u32, 256, 1024, 4096];
    let (ref_spp, ref_runs) = (512u32, 32u32);
    println!(
        "bunny_lowres × 0.1, {n} vertices, Lambert {ALBEDO}, courtyard.exr; reference: path \
         tracer {ref_runs} runs × {ref_spp} spp = {} spp per vertex",
        ref_spp * ref_runs
    );
    for bounces in [0u32, 1] {
        let t = Instant::now();
        let reference = reference(&scene, &vertices, bounces, ref_spp, ref_runs);
        let pt_noise = noise(&reference);
        println!(
            "\nbounces = {bounces}: reference in {:.1} s, its relative RMS noise {:.3} %",
            t.elapsed().as_secs_f64(),
            100.0 * pt_noise
        );
        // A bake at order n is the first n² coefficients of the same bake at a higher order
        // (same rays and seed: every coefficient is estimated from the same directions, and
        // bounce gathering is linear per coefficient), which we check once here; so each ray
        // count is baked once at the highest order and truncated.
        let max_order = *orders.last().unwrap();
        let mut table = vec![vec![0.0; rays.len()]; orders.len()];
        // A 16× larger ray count: its own Monte Carlo error is ≈ 4× below the 4096-ray bake's,
        // so (1) bake-vs-bake differences isolate the Monte Carlo part of each setting, without
        // the reference's noise, and (2) its error against the reference is (nearly) the
        // truncation and the other systematic differences alone.
        let t = Instant::now();
        let dense = bake(&scene, &accel, &settings(max_order, DENSE_RAYS, bounces)).unwrap();
        println!(
            "  {DENSE_RAYS} rays: order-{max_order} bake in {:.1} s",
            t.elapsed().as_secs_f64()
        );
        let dense_relit: Vec<Vec<[f64; 3]>> = orders.iter().map(|&o| relit(&dense, o)).collect();
        let mut mc = vec![vec![0.0; rays.len()]; orders.len()];
        for (j, &r) in rays.iter().enumerate() {
            let t = Instant::now();
            let out = bake(&scene, &accel, &settings(max_order, r, bounces)).unwrap();
            let secs = t.elapsed().as_secs_f64();
            let back = out.report.objects[0].backface_fraction;
            for (i, &o) in orders.iter().enumerate() {
                let here = relit(&out, o);
                table[i][j] = rel_rms(&here, &vertices, &reference);
                mc[i][j] = rel_diff(&here, &dense_relit[i], &reference);
            }
            if j == 1 {
                let low = bake(&scene, &accel, &settings(4, r, bounces)).unwrap();
                let (a, b) = (relit(&low, 4), relit(&out, 4));
                let diff = a
                    .iter()
                    .zip(&b)
                    .flat_map(|(x, y)| (0..3).map(move |c| (x[c] - y[c]).abs()))
                    .fold(0.0f64, f64::max);
                println!("  order-4 bake vs order-{max_order} bake truncated to 4 ({r} rays): max |Δ| = {diff:.2e}");
                assert!(diff < 1e-5, "truncation is not a lower-order bake: {diff}");
            }
            println!(
                "  {r} rays: order-{max_order} bake in {secs:.1} s, {:?}, rays hitting the mesh {:.2} %, back faces {:.2} %",
                out.report.objects[0].kinds,
                100.0 * out.report.objects[0].hit_fraction,
                100.0 * back
            );
        }
        let mean = reference
            .radiance
            .iter()
            .map(|r| r.iter().sum::<f64>())
            .sum::<f64>()
            / (3 * n) as f64;
        println!("  mean reference radiance {mean:.4}");
        let unshadowed = unshadowed_truncation(&scene, &orders);
        println!(
            "\nbounces = {bounces}: relative RMS error over vertices, raw (in brackets: with the \
             reference's noise {:.2} % removed, sqrt(e² − σ²))",
            100.0 * pt_noise
        );
        println!(
            "\n| order | {} rays | unshadowed truncation alone |",
            rays.map(|r| r.to_string()).join(" rays | ")
        );
        println!("|---|{}---|", "---|".repeat(rays.len()));
        for (i, o) in orders.iter().enumerate() {
            let cells: Vec<String> = table[i]
                .iter()
                .map(|e| {
                    let c = (e * e - pt_noise * pt_noise).max(0.0).sqrt();
                    format!("{:.2} % ({:.2} %)", 100.0 * e, 100.0 * c)
                })
                .collect();
            println!(
                "| {o} | {} | {:.3} % |",
                cells.join(" | "),
                100.0 * unshadowed[i]
            );
        }
        println!(
            "\nbounces = {bounces}: the two parts. Monte Carlo: relative RMS difference to the \
             {DENSE_RAYS}-ray bake of the same order. Systematic: the {DENSE_RAYS}-ray bake \
             against the reference, its noise removed."
        );
        println!(
            "\n| order | Monte Carlo, {} rays | systematic ({DENSE_RAYS} rays vs reference) |",
            rays.map(|r| r.to_string()).join(" rays | ")
        );
        println!("|---|{}---|", "---|".repeat(rays.len()));
        for (i, o) in orders.iter().enumerate() {
            let cells: Vec<String> = mc[i]
                .iter()
                .map(|e| format!("{:.2} %", 100.0 * e))
                .collect();
            let e = rel_rms(&dense_relit[i], &vertices, &reference);
            let sys = (e * e - pt_noise * pt_noise).max(0.0).sqrt();
            println!("| {o} | {} | {:.2} % |", cells.join(" | "), 100.0 * sys);
        }
    }
}

#[test]
fn bake_converges_to_path_tracer() {
    // The study's setting (bunny, courtyard, bounces 0) on every 3rd vertex with a 4096-spp
    // reference (4 runs × 1024), so that it runs in a few seconds in release.
    let scene = bunny_scene();
    let accel = Accel::build(&scene).unwrap();
    let vertices: Vec<usize> = (0..scene.meshes[0].positions.len()).step_by(3).collect();
    let reference = reference(&scene, &vertices, 0, 1024, 4);
    let sigma = noise(&reference);
    let many = bake(&scene, &accel, &settings(8, 1024, 0)).unwrap();
    let few = bake(&scene, &accel, &settings(8, 64, 0)).unwrap();
    let e2 = rel_rms(&relit(&many, 2), &vertices, &reference);
    let e8 = rel_rms(&relit(&many, 8), &vertices, &reference);
    let e8_few = rel_rms(&relit(&few, 8), &vertices, &reference);
    eprintln!(
        "{} vertices, reference noise {:.2} %: order 2 {:.2} %, order 8 {:.2} % (1024 rays), \
         order 8 {:.2} % (64 rays)",
        vertices.len(),
        100.0 * sigma,
        100.0 * e2,
        100.0 * e8,
        100.0 * e8_few
    );
    // (a) Order: at order 2 the truncation dominates (the study: 27 % whatever the rays, 25 %
    // for the clamped cosine alone); at order 8 with 1024 rays it is 1.1 % plus the
    // reference's noise (≈ 1.5 % here). A factor 4 is far inside that.
    assert!(e8 < e2 / 4.0, "order 8 {e8} vs order 2 {e2}");
    // (b) Rays: at order 8, 64 rays leave ≈ 6 % of error (64 rays cannot pin down 64
    // coefficients), 1024 rays 1.1 % (the study); both carry the same reference noise. Ask
    // for a factor 1.5 on the raw figures.
    assert!(e8 * 1.5 < e8_few, "1024 rays {e8} vs 64 rays {e8_few}");
    // (c) Absolute: E[e²] = e_true² + σ² (the reference's noise is independent of the bake).
    // e_true at order 8 / 1024 rays is the truncation of the shadowed transfer (at least the
    // clamped cosine's own tail, 0.34 % of the unshadowed radiance for this map at order 8,
    // computed exactly in the study; visibility adds more) plus the bake's Monte Carlo error:
    // the study (crates/bake/README.md) measures 1.1 % for the two together against a
    // 16384-spp reference (0.99 % systematic, 0.53 % Monte Carlo); we allow 3 %. The σ² term gets a factor 2 for the fluctuation of the
    // noise sum over ~600 × 3 terms and of σ estimated from 4 runs.
    let bound = 0.03;
    assert!(
        e8 * e8 < bound * bound + 2.0 * sigma * sigma,
        "order 8 / 1024 rays: {e8} exceeds sqrt({bound}² + 2 σ²) with σ = {sigma}"
    );
}
