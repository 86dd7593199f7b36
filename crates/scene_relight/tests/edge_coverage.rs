//! Image formation at edges: a per-vertex image is the box filter of each pixel, as the path
//! tracer's reference is, so a pixel that an edge cuts must hold each side in proportion to
//! its area. A 3 × 3 grid of sub-pixel rays measures that area to within 1/6 of the pixel (an
//! edge through a border strip of the pixel is not seen at all), which on a gold bunny under
//! the courtyard map held the relit image at 39 dB against the path tracer while its inside
//! matched to 45 dB; pixels that may hold an edge are now traced on a 16 × 16 grid
//! (`prt_scene_relight::imaging::pixel_samples`).
//!
//! The test: a square of constant radiance `q` (set directly as the relit vertex radiance;
//! only image formation is under test) seen from above at a slant, rotated so its projected
//! edges cross the pixels at every offset, in front of a constant background `B`. Each pixel's
//! exact value is `B + (q − B)·c` with `c` the area of the pixel covered by the projected
//! square (a convex polygon, clipped to the pixel exactly). Bound: a `k × k` midpoint grid
//! counts, in each of the `k` columns an edge crosses (rows for steep edges), the midpoints
//! below the edge's height at the column's centre, which is the column's exact area rounded
//! to a multiple of `1/k²` at most `1/(2k²)` off: `1/(2k)` per edge for the pixel, `1/k` in
//! pixels that hold a corner (two edges). With `k = 16` that is 1/32 (1/16) of the contrast
//! `|q − B|`; a pixel left on the 3 × 3 grid may be off by 1/6, and the test checks that such
//! pixels exist (an edge within a sixth of a pixel's side). Measured: the worst pixel is off by
//! 0.7 % of the contrast; skipping the neighbours' test (an edge seen by no ray of the pixel)
//! fails at 5.6 % coverage, and tracing no pixel on the fine grid fails too.

use prt_scene_relight::relit::{RelightStats, Relit};
use std::path::Path;

/// The square's corners projected to continuous image coordinates (x right, y down, pixel
/// `(i, j)` covering `[i, i+1) × [j, j+1)`), using the pinhole model of CONVENTIONS.md; each
/// checked against the camera's own ray through that image point.
fn project(scene: &prt_scene::Scene, corners: &[glam::DVec3]) -> Vec<[f64; 2]> {
    let c = &scene.camera;
    let forward = (c.target - c.eye).normalize();
    let right = forward.cross(c.up).normalize();
    let up = right.cross(forward);
    let tan = (c.fov_y_deg.to_radians() / 2.0).tan();
    let aspect = f64::from(c.width) / f64::from(c.height);
    let cam = prt_tracer::PinholeCamera::new(c).unwrap();
    corners
        .iter()
        .map(|p| {
            let d = *p - c.eye;
            let (sx, sy) = (d.dot(right) / d.dot(forward), d.dot(up) / d.dot(forward));
            let x = (sx / (tan * aspect) + 1.0) * f64::from(c.width) / 2.0;
            let y = (1.0 - sy / tan) * f64::from(c.height) / 2.0;
            let ray = cam.direction(x, y).as_dvec3();
            assert!(
                ray.cross(d.normalize()).length() < 1e-6,
                "projection of {p}"
            );
            [x, y]
        })
        .collect()
}

/// Area of the convex polygon `poly` inside the unit box at `(x0, y0)` (Sutherland–Hodgman
/// clipping against the four sides, then the shoelace formula).
fn covered(poly: &[[f64; 2]], x0: f64, y0: f64) -> f64 {
    let mut p = poly.to_vec();
    // Keep the side where `f(v) ≥ 0` of each box edge.
    let sides: [(usize, f64, f64); 4] = [
        (0, x0, 1.0),
        (0, x0 + 1.0, -1.0),
        (1, y0, 1.0),
        (1, y0 + 1.0, -1.0),
    ];
    for (axis, at, sign) in sides {
        let f = |v: &[f64; 2]| sign * (v[axis] - at);
        let mut out = Vec::new();
        for i in 0..p.len() {
            let (a, b) = (p[i], p[(i + 1) % p.len()]);
            let (fa, fb) = (f(&a), f(&b));
            if fa >= 0.0 {
                out.push(a);
            }
            if (fa >= 0.0) != (fb >= 0.0) {
                let t = fa / (fa - fb);
                out.push([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
            }
        }
        p = out;
        if p.is_empty() {
            return 0.0;
        }
    }
    let mut area = 0.0;
    for i in 0..p.len() {
        let (a, b) = (p[i], p[(i + 1) % p.len()]);
        area += a[0] * b[1] - b[0] * a[1];
    }
    area.abs() / 2.0
}

#[test]
fn edge_pixels_hold_each_side_in_proportion_to_its_area() {
    let dir = tempfile::tempdir().unwrap();
    let hard = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/hard");
    let scene_path = dir.path().join("edge.toml");
    std::fs::write(
        &scene_path,
        format!(
            r#"[camera]
eye = [0.3, 3.0, 0.9]
target = [0.0, 0.0, 0.0]
up = [0.14, 0.0, -0.99]
fov_y = 50.0
resolution = [64, 48]

[environment]
file = "{}"

[materials.grey]
type = "lambert"
albedo = [0.5, 0.5, 0.5]

[[objects]]
mesh = "{}"
material = "grey"
rotate = [0.0, 11.0, 0.0]
"#,
            hard.join("uniform.hdr").display(),
            hard.join("quad.obj").display()
        ),
    )
    .unwrap();
    let scene = prt_scene::load_scene(&scene_path).unwrap().scene;
    let accel = prt_tracer::Accel::build(&scene).unwrap();
    let q = 0.2f32;
    let relit = Relit {
        radiance: vec![vec![[q; 3]; scene.meshes[0].positions.len()]],
        roi: vec![Vec::new()],
        stats: RelightStats::default(),
        footprints: None,
        lightmaps: Vec::new().into(),
        emission: false,
        shrm: Vec::new(),
    };
    let image = prt_scene_relight::form_image(&scene, &accel, &relit, 0.0).unwrap();
    let (w, h) = (image.width as usize, image.height as usize);
    // The square's outline, in the order its two triangles' outer edges run.
    let m = &scene.meshes[0];
    let corners: Vec<glam::DVec3> = [0usize, 1, 2, 3]
        .iter()
        .map(|&i| m.positions[i].as_dvec3())
        .collect();
    let poly = project(&scene, &corners);
    let b = image.pixels[0][0];
    let contrast = f64::from((q - b).abs());
    assert!(contrast > 0.5, "background {b}");
    let (mut edge, mut strip, mut worst) = (0, 0, 0.0f64);
    for y in 0..h {
        for x in 0..w {
            let c = covered(&poly, x as f64, y as f64);
            let exact = f64::from(b) + f64::from(q - b) * c;
            let got = f64::from(image.pixels[y * w + x][0]);
            let corner = poly.iter().any(|p| {
                p[0] >= x as f64
                    && p[0] < x as f64 + 1.0
                    && p[1] >= y as f64
                    && p[1] < y as f64 + 1.0
            });
            let k = f64::from(prt_scene_relight::imaging::EDGE_SUBPIXELS);
            let bound = contrast * if corner { 1.0 / k } else { 0.5 / k } + 1e-5;
            if c > 1e-9 && c < 1.0 - 1e-9 {
                edge += 1;
                worst = worst.max((got - exact).abs() / contrast);
                // An edge within a sixth of the side: the 3 × 3 grid's outer rays miss it.
                if !(1.0 / 6.0..=5.0 / 6.0).contains(&c) {
                    strip += 1;
                }
            }
            // The probe of `prt relight --target-psnr` forms single pixels from the same rays.
            let cam = prt_tracer::PinholeCamera::new(&scene.camera).unwrap();
            let samples =
                prt_scene_relight::imaging::pixel_samples(&cam, &accel, x as u32, y as u32);
            let mean = samples
                .iter()
                .map(|(_, hit)| if hit.is_some() { q } else { b })
                .sum::<f32>()
                / samples.len() as f32;
            assert!(
                (f64::from(mean) - got).abs() <= 1e-6,
                "pixel ({x}, {y}): probe {mean} vs image {got}"
            );
            assert!(
                (got - exact).abs() <= bound,
                "pixel ({x}, {y}): {got} vs exact {exact} (coverage {c:.4}, bound {bound})"
            );
        }
    }
    eprintln!("{edge} edge pixels ({strip} with coverage below 1/6 or above 5/6); worst {worst:.4} of the contrast");
    assert!(
        edge > 60 && strip > 10,
        "{edge} edge pixels, {strip} in the border strips"
    );
}
