#!/usr/bin/env python3
"""Render one scene with Mitsuba 3's `path` integrator and with `prt render`; report the
difference against the two renders' own noise.

Setup (once): python3 -m venv tools/.venv && tools/.venv/bin/pip install mitsuba numpy
Run:          tools/.venv/bin/python tools/mitsuba_compare.py [--spp 64] [--bounces 1]

The script writes its own comparison scene into --work (default out/mitsuba_compare/) so both
renderers see identical inputs, following the Mitsuba caveats of shared/FACTS.md:
- meshes are written as OBJ *with* `vn` lines (area-weighted vertex normals computed here),
  so Mitsuba does not compute its own shading normals;
- the environment is a small piecewise-constant lat-long map (scenes/maps/courtyard.exr,
  box-averaged to 64×32); Mitsuba gets it upsampled by nearest neighbour (×16 by default,
  `--upsample`), because its `envmap` looks texels up bilinearly with rows at v = j/(H−1):
  the bilinear blend then only touches 1/16 of each texel next to its edges, which still
  shows in background pixels (they display the map directly), so statistics are reported
  separately for background and surface pixels (our depth AOV tells them apart);
- materials are Lambertian only (Mitsuba has no Phong/Ward; its microfacet models differ);
- Mitsuba `max_depth = bounces + 2`, box pixel filter, `fov_axis = "y"`.

Noise model: our EXR carries a per-pixel variance of the mean (`variance.*`, `--aovs`);
Mitsuba's is estimated from two independent renders (seeds 0 and 1) as (a − b)² / 2 per
pixel, averaged over the image. For unbiased renderers of the same image,
E[MSE(ours, mitsuba)] = mean var(ours) + mean var(mitsuba), so the reported
`mse_ratio` = MSE / that sum should be ≈ 1; a bias shows up as a ratio well above 1 and as a
large |z| of the image-mean difference.

Suite mode (`--suite`): one command renders six scenes with prt and with Mitsuba 3's
`scalar_rgb` and `llvm_ad_rgb` variants and prints two Markdown tables (also suite.json, PNG
views and per-pixel z maps in <work>/suite/):
  tools/.venv/bin/python tools/mitsuba_compare.py --suite [--spp 1024] [--repeats 3]
      [--prt PATH] [--scenes sphere,bunny_floor,mirror,far,millimetre,teapot] [--ref-factor 16]
- scenes: `sphere` (Lambert, 0 bounces), `bunny_floor` (full-res bunny 1 tall on a floor, 1),
  `mirror` (teapot with our `mirror` material on a floor, 2; in Mitsuba a `blendbsdf` of
  `diffuse` albedo/(1−w) and a `conductor` "none" of reflectance specular/w, w = s/(a+s)),
  `far` (bunny_floor translated by (577, 577, 577), camera too), `millimetre` (teapot 1 mm
  wide resting exactly on a ±3 m two-triangle floor, 1), `teapot` (rotated by prt's `rotate`
  key, Mitsuba gets the same T·Rz·Ry·Rx·S matrix, 1). All Mitsuba BSDFs are `twosided`
  (prt shades back faces as front faces); perspective near_clip scales with the scene.
- timing: prt = whole process (median of --repeats, seeds 0..R−1); Mitsuba = `mi.render` only
  (scene loading excluded), median of --repeats, each variant in its own process; llvm_ad_rgb
  first does one warm-up render (its time is reported as "first": JIT tracing + compilation or
  Dr.Jit's on-disk kernel cache).
- reference: llvm_ad_rgb, --ref-factor passes of --spp (16 → its noise is 1/4 of one image's),
  cached in <work>/suite/refs by content, rendered with the scene in *canonical placement*
  (translation removed, scale 1): radiance under a distant map does not change under those maps,
  but Mitsuba's ray offset (1 + max|p|)·8.9e-5 does, so the native-placement Mitsuba reference of
  `far` and `millimetre` is also rendered and compared (last column of the second table).
- relL2 = sqrt(Σ(a−ref)²/Σref²) over all and over surface pixels (prt depth AOV ≠ 0); cost =
  seconds × relL2²; cost ratios prt/scalar and prt/llvm (< 1: prt cheaper). The bias check is the
  statistic above, of each image against the reference (the reference's variance from the spread
  of its passes, a Mitsuba image's from the spread of its --repeats seeds), plus the single-scene
  form (prt against the mean of two scalar_rgb renders); pixels beyond 5 standard errors are
  grouped into clusters in suite.json (`outliers_*`: box, part/floor/background, distance to the
  part in pixels, mean z).
"""

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def read_obj(path):
    verts, faces = [], []
    with open(path) as f:
        for line in f:
            parts = line.split()
            if not parts:
                continue
            if parts[0] == "v":
                verts.append([float(x) for x in parts[1:4]])
            elif parts[0] == "f":
                idx = [int(p.split("/")[0]) for p in parts[1:]]
                idx = [i - 1 if i > 0 else len(verts) + i for i in idx]
                for k in range(1, len(idx) - 1):
                    faces.append([idx[0], idx[k], idx[k + 1]])
    return np.array(verts, dtype=np.float64), np.array(faces, dtype=np.int64)


def area_weighted_normals(verts, faces):
    tri = verts[faces]
    face_n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])  # length = 2·area
    normals = np.zeros_like(verts)
    for k in range(3):
        np.add.at(normals, faces[:, k], face_n)
    return normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-30)


def write_obj_with_normals(path, verts, faces, normals=None):
    """Writes `v`, `vn` (one per vertex: `normals`, else area-weighted) and `f v//vn` lines."""
    if normals is None:
        normals = area_weighted_normals(verts, faces)
    with open(path, "w") as f:
        f.write("# written by tools/mitsuba_compare.py\n")
        for v in verts:
            f.write(f"v {v[0]:.9g} {v[1]:.9g} {v[2]:.9g}\n")
        for n in normals:
            f.write(f"vn {n[0]:.9g} {n[1]:.9g} {n[2]:.9g}\n")
        for t in faces + 1:
            f.write(f"f {t[0]}//{t[0]} {t[1]}//{t[1]} {t[2]}//{t[2]}\n")


def read_exr_channels(mi, path):
    bmp = mi.Bitmap(path)
    names = [field.name for field in bmp.struct_()]
    data = np.array(bmp, dtype=np.float64).reshape(bmp.height(), bmp.width(), len(names))
    return {name: data[..., k] for k, name in enumerate(names)}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--spp", type=int, default=None, help="default 64 (1024 with --suite)")
    ap.add_argument("--bounces", type=int, default=1)
    ap.add_argument("--width", type=int, default=160)
    ap.add_argument("--height", type=int, default=120)
    ap.add_argument("--work", default=os.path.join(ROOT, "out", "mitsuba_compare"))
    ap.add_argument("--prt", default=os.path.join(ROOT, "target", "release", "prt"))
    ap.add_argument("--variant", default="scalar_rgb")
    ap.add_argument("--upsample", type=int, default=16,
                    help="nearest-neighbour upsampling of the map for Mitsuba (FACTS.md says ×4; "
                         "more shrinks the bilinear blend zone at texel edges)")
    ap.add_argument("--suite", action="store_true",
                    help="render the six-scene suite with prt, Mitsuba scalar_rgb and llvm_ad_rgb "
                         "(see 'Suite mode' above)")
    ap.add_argument("--repeats", type=int, default=3, help="--suite: timed runs per renderer (median)")
    ap.add_argument("--scenes", default=",".join(SUITE_SCENES),
                    help="--suite: comma-separated subset of " + ",".join(SUITE_SCENES))
    ap.add_argument("--ref-factor", type=int, default=16,
                    help="--suite: the reference is this many llvm_ad_rgb passes of --spp each")
    ap.add_argument("--worker", help=argparse.SUPPRESS)  # internal: one Mitsuba variant per process
    args = ap.parse_args()
    if args.worker:
        return mitsuba_worker(args.worker)
    if args.spp is None:
        args.spp = 1024 if args.suite else 64
    if args.suite:
        return suite(args)
    single(args)


def write_env(mi, work, upsample, big_name="env_x4.exr"):
    """Courtyard box-averaged to 64×32, negatives clamped (as our loader does): `env.exr` for
    prt, and the same map upsampled by nearest neighbour for Mitsuba (`big_name`)."""
    src = np.array(mi.Bitmap(os.path.join(ROOT, "scenes", "maps", "courtyard.exr")).convert(
        mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32, srgb_gamma=False), dtype=np.float64)
    src = np.maximum(src, 0.0)
    h, wd = src.shape[:2]
    small = src.reshape(32, h // 32, 64, wd // 64, 3).mean(axis=(1, 3)).astype(np.float32)
    mi.Bitmap(small).write(os.path.join(work, "env.exr"))
    big = np.ascontiguousarray(np.repeat(np.repeat(small, upsample, axis=0), upsample, axis=1))
    mi.Bitmap(big).write(os.path.join(work, big_name))


def single(args):
    import mitsuba as mi

    mi.set_variant(args.variant)
    os.makedirs(args.work, exist_ok=True)
    w = lambda name: os.path.join(args.work, name)

    write_env(mi, args.work, args.upsample)

    # Meshes with vn: the low-resolution bunny scaled by 0.1 on a 4×4 floor.
    verts, faces = read_obj(os.path.join(ROOT, "scenes", "meshes", "bunny_lowres.obj"))
    write_obj_with_normals(w("bunny.obj"), verts * 0.1, faces)
    floor_v = np.array([[-2, 0, -2], [-2, 0, 2], [2, 0, 2], [2, 0, -2]], dtype=np.float64)
    write_obj_with_normals(w("floor.obj"), floor_v, np.array([[0, 1, 2], [0, 2, 3]]))

    eye, target, up, fov = [0.0, 0.75, 2.4], [0.0, 0.42, 0.0], [0.0, 1.0, 0.0], 40.0
    with open(w("scene.toml"), "w") as f:
        f.write(f"""# Written by tools/mitsuba_compare.py.
[camera]
eye = {eye}
target = {target}
up = {up}
fov_y = {fov}
resolution = [{args.width}, {args.height}]

[environment]
file = "env.exr"
mapping = "latlong"

[materials.clay]
type = "lambert"
albedo = [0.8, 0.7, 0.6]

[materials.floor]
type = "lambert"
albedo = [0.5, 0.5, 0.5]

[[objects]]
mesh = "bunny.obj"
material = "clay"

[[objects]]
mesh = "floor.obj"
material = "floor"

[render]
spp = {args.spp}
bounces = {args.bounces}
seed = 0
""")

    # Ours.
    t0 = time.time()
    cmd = [args.prt, "render", w("scene.toml"), "--spp", str(args.spp), "--bounces", str(args.bounces),
           "--aovs", "--quiet", "--out", w("ours.exr")]
    run = subprocess.run(cmd, capture_output=True, text=True)
    ours_wall = time.time() - t0
    if run.returncode != 0:
        sys.exit(f"prt render failed: {run.stderr}")
    ch = read_exr_channels(mi, w("ours.exr"))
    ours = np.stack([ch["R"], ch["G"], ch["B"]], axis=-1)
    ours_var = np.stack([ch["variance.R"], ch["variance.G"], ch["variance.B"]], axis=-1)

    # Mitsuba, twice.
    def mitsuba_render(seed):
        scene = mi.load_dict({
            "type": "scene",
            "integrator": {"type": "path", "max_depth": args.bounces + 2 if args.bounces >= 0 else -1},
            "sensor": {
                "type": "perspective", "fov": fov, "fov_axis": "y",
                "to_world": mi.ScalarTransform4f().look_at(origin=eye, target=target, up=up),
                "film": {"type": "hdrfilm", "width": args.width, "height": args.height,
                         "rfilter": {"type": "box"}, "pixel_format": "rgb"},
                "sampler": {"type": "independent", "sample_count": args.spp},
            },
            "env": {"type": "envmap", "filename": w("env_x4.exr")},
            "bunny": {"type": "obj", "filename": w("bunny.obj"),
                      "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.8, 0.7, 0.6]}}},
            "floor": {"type": "obj", "filename": w("floor.obj"),
                      "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.5, 0.5, 0.5]}}},
        })
        t = time.time()
        img = mi.render(scene, seed=seed, spp=args.spp)
        secs = time.time() - t
        return np.array(img, dtype=np.float64)[..., :3], secs

    m0, t_m0 = mitsuba_render(0)
    m1, _ = mitsuba_render(1)
    mi.Bitmap(m0.astype(np.float32)).write(w("mitsuba.exr"))
    mits = 0.5 * (m0 + m1)
    background = (ch["depth.Z"] == 0.0)[..., None].repeat(3, axis=-1)

    def stats(mask):
        mits_var_single = float(np.mean(((m0 - m1) ** 2)[mask]) / 2.0)  # one render's pixel variance
        ours_var_mean = float(np.mean(ours_var[mask]))
        expected = ours_var_mean + mits_var_single / 2.0  # `mits` averages two renders
        diff = (ours - mits)[mask]
        mse = float(np.mean(diff ** 2))
        se_mean = float(np.sqrt(expected / diff.size))
        return {
            "pixels": int(mask.sum() // 3),
            "mean_ours": float(np.mean(ours[mask])), "mean_mitsuba": float(np.mean(mits[mask])),
            "relative_mean_difference": float(np.mean(diff)) / float(np.mean(mits[mask])),
            "mean_difference_z": float(np.mean(diff)) / se_mean,
            "mse": mse, "mse_expected_from_noise": expected, "mse_ratio": mse / expected,
            "rmse_ours_noise": float(np.sqrt(ours_var_mean)),
            "rmse_mitsuba_noise": float(np.sqrt(mits_var_single)),
        }

    report = {
        "spp": args.spp, "bounces": args.bounces, "size": [args.width, args.height],
        "env_upsample_for_mitsuba": args.upsample,
        "surfaces": stats(~background), "background": stats(background), "all": stats(np.ones_like(background)),
        "seconds_prt_wall": ours_wall,
        "seconds_mitsuba_one_render": t_m0, "mitsuba_variant": args.variant,
    }
    with open(w("report.json"), "w") as f:
        json.dump(report, f, indent=2)
    print(json.dumps(report, indent=2))


# ---------------------------------------------------------------------------------------------
# Suite mode (--suite): six scenes, prt vs Mitsuba 3 scalar_rgb and llvm_ad_rgb, one table.
# ---------------------------------------------------------------------------------------------

SUITE_SCENES = ["sphere", "bunny_floor", "mirror", "far", "millimetre", "teapot"]
LLVM_LIB = os.path.join(ROOT, "tools", ".venv", "llvm19", "usr", "lib", "x86_64-linux-gnu",
                        "libLLVM.so.19.1")
SUITE_UPSAMPLE_NAME = "env_up.exr"

SUITE_MATERIALS = {
    "clay": {"type": "lambert", "albedo": [0.8, 0.7, 0.6]},
    "floor": {"type": "lambert", "albedo": [0.5, 0.5, 0.5]},
    # grey on purpose: Mitsuba's blend weight w = s / (a + s) is one scalar for all channels.
    "chrome": {"type": "mirror", "albedo": [0.2, 0.2, 0.2], "specular": [0.6, 0.6, 0.6]},
}


def read_obj_full(path):
    """Like read_obj, but keeps the file's `vn` normals: returns (verts, normals or None, faces)
    with one vertex per distinct (v, vn) pair."""
    verts, norms, corners = [], [], []
    with open(path) as f:
        for line in f:
            parts = line.split()
            if not parts:
                continue
            if parts[0] == "v":
                verts.append([float(x) for x in parts[1:4]])
            elif parts[0] == "vn":
                norms.append([float(x) for x in parts[1:4]])
            elif parts[0] == "f":
                cs = []
                for p in parts[1:]:
                    q = p.split("/")
                    vi = int(q[0])
                    vi = vi - 1 if vi > 0 else len(verts) + vi
                    ni = -1
                    if len(q) >= 3 and q[2]:
                        ni = int(q[2])
                        ni = ni - 1 if ni > 0 else len(norms) + ni
                    cs.append((vi, ni))
                for k in range(1, len(cs) - 1):
                    corners.append((cs[0], cs[k], cs[k + 1]))
    verts = np.array(verts, dtype=np.float64)
    if not norms or any(c[1] < 0 for t in corners for c in t):
        return verts, None, np.array([[c[0] for c in t] for t in corners], dtype=np.int64)
    norms = np.array(norms, dtype=np.float64)
    index, out_v, out_n, out_f = {}, [], [], []
    for t in corners:
        row = []
        for c in t:
            if c not in index:
                index[c] = len(out_v)
                out_v.append(verts[c[0]])
                out_n.append(norms[c[1]])
            row.append(index[c])
        out_f.append(row)
    n = np.array(out_n)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return np.array(out_v), n, np.array(out_f, dtype=np.int64)


def euler_matrix(rotate_deg):
    """prt's `rotate = [x, y, z]` (degrees): R = Rz · Ry · Rx (crates/scene/src/mesh.rs)."""
    x, y, z = np.radians(rotate_deg)
    rx = np.array([[1, 0, 0], [0, np.cos(x), -np.sin(x)], [0, np.sin(x), np.cos(x)]])
    ry = np.array([[np.cos(y), 0, np.sin(y)], [0, 1, 0], [-np.sin(y), 0, np.cos(y)]])
    rz = np.array([[np.cos(z), -np.sin(z), 0], [np.sin(z), np.cos(z), 0], [0, 0, 1]])
    return rz @ ry @ rx


def object_matrix(translate, rotate, scale):
    """prt's object transform T · R · S as a 4×4 matrix (the same one is given to Mitsuba)."""
    m = np.eye(4)
    m[:3, :3] = euler_matrix(rotate) @ np.diag(scale)
    m[:3, 3] = translate
    return m


def write_suite_meshes(work):
    """Meshes of the suite, all with `vn` lines, in their canonical (unit-size) placement."""
    w = lambda name: os.path.join(work, name)
    v, n, f = read_obj_full(os.path.join(ROOT, "scenes", "hard", "sphere.obj"))
    write_obj_with_normals(w("sphere.obj"), v, f, n)  # the file's own (analytic) normals
    # Full-resolution bunny: 1 tall, centred in x and z, lowest vertex exactly at y = 0.
    v, f = read_obj(os.path.join(ROOT, "scenes", "meshes", "bunny.obj"))
    lo, hi = v.min(axis=0), v.max(axis=0)
    v = (v - np.array([(lo[0] + hi[0]) / 2, lo[1], (lo[2] + hi[2]) / 2])) / (hi[1] - lo[1])
    write_obj_with_normals(w("bunny_full.obj"), v, f)
    # Teapot as stored (Z up, about 6.4 wide), rotated by the scene file in the `teapot` scene.
    v, f = read_obj(os.path.join(ROOT, "scenes", "meshes", "teapot.obj"))
    write_obj_with_normals(w("teapot_raw.obj"), v, f)
    # Teapot stood up (Y up: (x, y, z) -> (x, z, -y)), 1 wide, lowest vertex exactly at y = 0.
    v = np.stack([v[:, 0], v[:, 2], -v[:, 1]], axis=1)
    lo, hi = v.min(axis=0), v.max(axis=0)
    v = (v - np.array([(lo[0] + hi[0]) / 2, lo[1], (lo[2] + hi[2]) / 2])) / np.max(hi - lo)
    write_obj_with_normals(w("teapot_unit.obj"), v, f)
    # Floor: one quad (two triangles) at y = 0, ±1, scaled by the scene.
    quad = np.array([[-1, 0, -1], [-1, 0, 1], [1, 0, 1], [1, 0, -1]], dtype=np.float64)
    write_obj_with_normals(w("quad.obj"), quad, np.array([[0, 1, 2], [0, 2, 3]]),
                           np.tile([0.0, 1.0, 0.0], (4, 1)))


def teapot_rest_translate(work, rotate, scale):
    """Translation that centres the rotated teapot in x/z and puts its lowest point on y = 0."""
    v, _ = read_obj(os.path.join(work, "teapot_raw.obj"))
    p = v @ (euler_matrix(rotate) @ np.diag(scale)).T
    lo, hi = p.min(axis=0), p.max(axis=0)
    return [-(lo[0] + hi[0]) / 2, -lo[1], -(lo[2] + hi[2]) / 2]


def suite_specs(work):
    """Scenes in canonical placement (unit-size, near the origin) plus a `placement` (s, t):
    the rendered scene is world = s · canonical + t. Radiance under a distant environment is
    invariant under that map, so the canonical scene's reference is the reference of both."""
    def obj(mesh, material, translate=(0, 0, 0), rotate=(0, 0, 0), scale=(1, 1, 1)):
        return {"mesh": mesh, "material": material, "translate": list(map(float, translate)),
                "rotate": list(map(float, rotate)), "scale": list(map(float, scale))}

    def cam(eye, target, fov):
        return {"eye": list(map(float, eye)), "target": list(map(float, target)), "up": [0.0, 1.0, 0.0],
                "fov": float(fov)}

    bunny_floor = {
        "bounces": 1, "camera": cam([0, 0.75, 2.4], [0, 0.42, 0], 40),
        "objects": [obj("bunny_full.obj", "clay"), obj("quad.obj", "floor", scale=(2, 1, 2))],
        "what": "full-res bunny (1 tall) on a 4x4 floor",
    }
    tp_rot, tp_scale = (-75.0, 40.0, 15.0), (0.25, 0.25, 0.25)
    specs = {
        "sphere": {
            "bounces": 0, "camera": cam([0, 0, 3.6], [0, 0, 0], 40),
            "objects": [obj("sphere.obj", "clay")], "what": "Lambert unit sphere, no floor",
        },
        "bunny_floor": bunny_floor,
        "mirror": {
            "bounces": 2, "camera": cam([0.55, 0.75, 1.55], [0, 0.22, 0], 36),
            "objects": [obj("teapot_unit.obj", "chrome"), obj("quad.obj", "floor", scale=(2, 1, 2))],
            "what": "mirror teapot (albedo 0.2 + specular 0.6) on a floor",
        },
        "far": dict(bunny_floor, placement=[1.0, [577.0, 577.0, 577.0]],
                    what="bunny_floor translated by (577, 577, 577) (|t| = 999.4), camera too"),
        "millimetre": {
            "bounces": 1, "camera": cam([0.45, 0.55, 1.25], [0, 0.2, 0], 36),
            "objects": [obj("teapot_unit.obj", "clay"), obj("quad.obj", "floor", scale=(3000, 1, 3000))],
            "placement": [1e-3, [0.0, 0.0, 0.0]],
            "what": "teapot 1 mm wide resting exactly on a ±3 m floor (2 triangles)",
        },
        "teapot": {
            "bounces": 1, "camera": cam([0, 0.85, 2.1], [0, 0.35, 0], 40),
            "objects": [obj("teapot_raw.obj", "clay", teapot_rest_translate(work, tp_rot, tp_scale), tp_rot,
                            tp_scale), obj("quad.obj", "floor", scale=(2, 1, 2))],
            "what": "teapot rotated by prt's rotate = [-75, 40, 15] (Rz·Ry·Rx), on a floor",
        },
    }
    for s in specs.values():
        s.setdefault("placement", [1.0, [0.0, 0.0, 0.0]])
    return specs


def placed(spec, canonical=False):
    """The spec's objects and camera in world space (identity placement when `canonical`)."""
    s, t = (1.0, np.zeros(3)) if canonical else (spec["placement"][0], np.array(spec["placement"][1]))
    objs = []
    for o in spec["objects"]:
        objs.append(dict(o, translate=list(s * np.array(o["translate"]) + t),
                         scale=list(s * np.array(o["scale"]))))
    c = spec["camera"]
    camera = dict(c, eye=list(s * np.array(c["eye"]) + t), target=list(s * np.array(c["target"]) + t),
                  near=1e-3 * s, far=1e5 * s)
    return objs, camera


def write_prt_toml(path, spec, args):
    objs, c = placed(spec)
    fmt = lambda v: "[" + ", ".join(repr(float(x)) for x in v) + "]"
    lines = ["# Written by tools/mitsuba_compare.py --suite: " + spec["what"], "[camera]",
             f"eye = {fmt(c['eye'])}", f"target = {fmt(c['target'])}", f"up = {fmt(c['up'])}",
             f"fov_y = {c['fov']!r}", f"resolution = [{args.width}, {args.height}]", "",
             "[environment]", 'file = "env.exr"', 'mapping = "latlong"', ""]
    for name in sorted({o["material"] for o in objs}):
        m = SUITE_MATERIALS[name]
        lines += [f"[materials.{name}]", f'type = "{m["type"]}"', f"albedo = {fmt(m['albedo'])}"]
        if "specular" in m:
            lines.append(f"specular = {fmt(m['specular'])}")
        lines.append("")
    for o in objs:
        lines += ["[[objects]]", f'mesh = "{o["mesh"]}"', f'material = "{o["material"]}"',
                  f"translate = {fmt(o['translate'])}", f"rotate = {fmt(o['rotate'])}",
                  f"scale = {fmt(o['scale'])}", ""]
    lines += ["[render]", f"spp = {args.spp}", f"bounces = {spec['bounces']}", "seed = 0", ""]
    with open(path, "w") as f:
        f.write("\n".join(lines))


def mitsuba_bsdf(name):
    m = SUITE_MATERIALS[name]
    rgb = lambda v: {"type": "rgb", "value": [float(x) for x in v]}
    if m["type"] == "lambert":
        inner = {"type": "diffuse", "reflectance": rgb(m["albedo"])}
    elif m["type"] == "mirror":
        # albedo/π + specular · perfect mirror = (1 − w) · diffuse(albedo/(1 − w)) + w · mirror(specular/w)
        a, sp = np.array(m["albedo"]), np.array(m["specular"])
        w = sp / (a + sp)
        assert np.allclose(w, w[0]), "mirror → blendbsdf needs one weight for all channels"
        w = float(w[0])
        inner = {"type": "blendbsdf", "weight": w,
                 "bsdf_0": {"type": "diffuse", "reflectance": rgb(a / (1 - w))},
                 "bsdf_1": {"type": "conductor", "material": "none", "specular_reflectance": rgb(sp / w)}}
    else:
        raise ValueError(m["type"])
    # prt shades both sides (a back-facing normal is flipped toward the viewer): so does twosided.
    return {"type": "twosided", "bsdf": inner}


def mitsuba_desc(spec, work, args, canonical=False):
    """A JSON-able description of the Mitsuba scene (the worker turns it into a dict)."""
    objs, cam = placed(spec, canonical)
    return {
        "width": args.width, "height": args.height, "max_depth": spec["bounces"] + 2,
        "camera": cam, "env": os.path.join(work, SUITE_UPSAMPLE_NAME),
        "shapes": [{"filename": os.path.join(work, o["mesh"]),
                    "to_world": object_matrix(o["translate"], o["rotate"], o["scale"]).tolist(),
                    "bsdf": mitsuba_bsdf(o["material"])} for o in objs],
    }


def build_mitsuba_scene(mi, desc, spp):
    cam = desc["camera"]
    d = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": desc["max_depth"]},
        "sensor": {
            "type": "perspective", "fov": cam["fov"], "fov_axis": "y",
            "near_clip": cam["near"], "far_clip": cam["far"],
            "to_world": mi.ScalarTransform4f().look_at(origin=cam["eye"], target=cam["target"], up=cam["up"]),
            "film": {"type": "hdrfilm", "width": desc["width"], "height": desc["height"],
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": spp},
        },
        "env": {"type": "envmap", "filename": desc["env"]},
    }
    for k, sh in enumerate(desc["shapes"]):
        d[f"shape{k}"] = {"type": "obj", "filename": sh["filename"],
                          "to_world": mi.ScalarTransform4f(np.array(sh["to_world"])), "bsdf": sh["bsdf"]}
    return mi.load_dict(d)


def mitsuba_worker(job_path):
    """Runs in its own process (one Mitsuba variant per process)."""
    with open(job_path) as f:
        job = json.load(f)
    if job["variant"].startswith("llvm") and "DRJIT_LIBLLVM_PATH" not in os.environ and os.path.exists(LLVM_LIB):
        os.environ["DRJIT_LIBLLVM_PATH"] = LLVM_LIB
    import mitsuba as mi

    mi.set_variant(job["variant"])
    spp = job["spp"]
    t = time.perf_counter()
    scene = build_mitsuba_scene(mi, job["desc"], spp)
    out = {"variant": job["variant"], "load_seconds": time.perf_counter() - t, "mitsuba": mi.__version__}

    def render(seed):
        t = time.perf_counter()
        img = mi.render(scene, seed=seed, spp=spp)
        a = np.array(img, dtype=np.float32)[..., :3]  # forces evaluation of a JIT variant
        return a, time.perf_counter() - t

    if job["mode"] == "timed":
        if job.get("warmup_seed") is not None:
            _, out["first_seconds"] = render(job["warmup_seed"])
        out["seconds"] = []
        for seed, path in zip(job["seeds"], job["outs"]):
            a, secs = render(seed)
            out["seconds"].append(secs)
            np.save(path, a)
        if "first_seconds" not in out:
            out["first_seconds"] = out["seconds"][0]
    else:  # reference: the mean of passes, with the variance of that mean from their spread
        s1 = s2 = 0.0
        out["seconds"] = []
        for seed in job["seeds"]:
            a, secs = render(seed)
            out["seconds"].append(secs)
            a = a.astype(np.float64)
            s1, s2 = s1 + a, s2 + a * a
        n = len(job["seeds"])
        mean = s1 / n
        var_pass = np.maximum(s2 / n - mean * mean, 0.0) * n / (n - 1)
        np.savez(job["out"], mean=mean, var_of_mean=var_pass / n)
    with open(job["result"], "w") as f:
        json.dump(out, f)


def run_worker(job, work, tag):
    path = os.path.join(work, f"job_{tag}.json")
    job["result"] = os.path.join(work, f"job_{tag}.result.json")
    with open(path, "w") as f:
        json.dump(job, f)
    run = subprocess.run([sys.executable, os.path.abspath(__file__), "--worker", path],
                         capture_output=True, text=True)
    if run.returncode != 0:
        sys.exit(f"Mitsuba worker {tag} failed ({run.returncode}):\n{run.stdout[-3000:]}\n{run.stderr[-3000:]}")
    with open(job["result"]) as f:
        return json.load(f)


def file_digest(path, _cache={}):
    if path not in _cache:
        import hashlib
        with open(path, "rb") as f:
            _cache[path] = hashlib.sha256(f.read()).hexdigest()
    return _cache[path]


def suite_reference(desc, args, work, tag, first_seed=1000):
    """llvm_ad_rgb, args.ref_factor passes of args.spp, cached under work/refs by content."""
    import hashlib
    key_src = json.dumps({"desc": desc, "spp": args.spp, "passes": args.ref_factor, "seed": first_seed,
                          "files": [file_digest(s["filename"]) for s in desc["shapes"]] + [file_digest(desc["env"])]},
                         sort_keys=True)
    key = hashlib.sha256(key_src.encode()).hexdigest()[:16]
    os.makedirs(os.path.join(work, "refs"), exist_ok=True)
    path = os.path.join(work, "refs", f"{tag}_{key}.npz")
    info = {"file": path, "spp_total": args.spp * args.ref_factor, "cached": os.path.exists(path)}
    if not info["cached"]:
        print(f"  reference {tag}: llvm_ad_rgb {args.ref_factor} × {args.spp} spp ...", file=sys.stderr, flush=True)
        res = run_worker({"variant": "llvm_ad_rgb", "mode": "reference", "spp": args.spp, "desc": desc,
                          "seeds": [first_seed + k for k in range(args.ref_factor)], "out": path}, work, f"ref_{tag}")
        info["seconds"] = sum(res["seconds"])
    z = np.load(path)
    return z["mean"], z["var_of_mean"], info


def rel_l2(a, ref, mask):
    return float(np.sqrt(np.sum((a - ref)[mask] ** 2) / np.sum(ref[mask] ** 2)))


def bias_stats(a, var_a, b, var_b, mask):
    """The statistic of the single-scene mode: `mse_ratio` = MSE / (expected MSE from the two
    images' noise) ≈ 1 and |z| of the mean difference small when they differ only by noise."""
    diff = (a - b)[mask]
    mse = float(np.mean(diff ** 2))
    expected = float(np.mean(var_a[mask]) + np.mean(var_b[mask]))
    return {
        "pixels": int(mask.sum() // 3), "mse": mse, "mse_expected_from_noise": expected,
        "mse_ratio": mse / expected,
        "mean_difference_z": float(np.mean(diff)) / float(np.sqrt(expected / diff.size)),
        "relative_mean_difference": float(np.mean(diff)) / float(np.mean(b[mask])),
    }


def pixel_z(a, var_a, b, var_b):
    """Channel-summed difference over its standard error. Pixels that see only one texel of
    the map have zero variance: a floor of 1e-5 of the value keeps f32 rounding from counting."""
    d = (a - b).sum(axis=-1)
    v = (var_a + var_b).sum(axis=-1) + (1e-5 * np.abs(b).sum(axis=-1)) ** 2
    return d / np.sqrt(np.maximum(v, 1e-30))


def outlier_clusters(a, var_a, b, var_b, part, surface, threshold=5.0, top=8):
    """Connected groups (8-neighbour) of surface pixels whose channel-summed difference exceeds
    `threshold` standard errors; each described by size, box, class and distance to the part."""
    h, wd = part.shape
    z = pixel_z(a, var_a, b, var_b)
    hot = np.abs(z) > threshold
    pixels_over = int(hot.sum())
    hot &= surface  # background pixels show Mitsuba's bilinear map lookup (see above), not news
    seen = np.zeros_like(hot)
    py, px = np.nonzero(part)
    out = []
    for y0, x0 in zip(*np.nonzero(hot)):
        if seen[y0, x0]:
            continue
        stack, pix = [(y0, x0)], []
        seen[y0, x0] = True
        while stack:
            y, x = stack.pop()
            pix.append((y, x))
            for dy in (-1, 0, 1):
                for dx in (-1, 0, 1):
                    yy, xx = y + dy, x + dx
                    if 0 <= yy < h and 0 <= xx < wd and hot[yy, xx] and not seen[yy, xx]:
                        seen[yy, xx] = True
                        stack.append((yy, xx))
        ys, xs = np.array(pix).T
        zs = z[ys, xs]
        if len(pix) < 2 and np.abs(zs).max() < 7:
            continue
        n_part = int(part[ys, xs].sum())
        n_bg = int((~surface[ys, xs]).sum())
        dist = [float(np.sqrt(np.min((py - y) ** 2 + (px - x) ** 2))) if len(py) else None
                for y, x in zip(ys, xs)] if n_part < len(pix) else [0.0]
        rd = float((a - b)[ys, xs].sum() / max(b[ys, xs].sum(), 1e-30))
        out.append({"pixels": len(pix), "x": [int(xs.min()), int(xs.max())], "y": [int(ys.min()), int(ys.max())],
                    "part": n_part, "floor": len(pix) - n_part - n_bg, "background": n_bg,
                    "max_px_from_part": max(d for d in dist if d is not None) if len(py) else None,
                    "mean_z": float(zs.mean()), "max_abs_z": float(np.abs(zs).max()),
                    "relative_difference": rd})
    out.sort(key=lambda c: -c["pixels"] * abs(c["mean_z"]))
    return {"threshold": threshold, "pixels_over": pixels_over, "surface_pixels_over": int(hot.sum()),
            "clusters": out[:top],
            "clusters_total": len(out)}


def write_png(path, img, scale_up=3):
    import imageio.v2 as imageio
    x = np.clip(img, 0.0, 1.0)
    x = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    x = np.repeat(np.repeat((x * 255 + 0.5).astype(np.uint8), scale_up, axis=0), scale_up, axis=1)
    imageio.imwrite(path, x)


def z_png(path, a, var_a, b, var_b, scale_up=3):
    z = pixel_z(a, var_a, b, var_b)
    img = np.zeros(z.shape + (3,))
    img[..., 0] = np.clip(z / 8, 0, 1)    # red: first image brighter
    img[..., 2] = np.clip(-z / 8, 0, 1)   # blue: first image darker
    img[..., 1] = 0.15 * (np.abs(z) > 5)
    write_png(path, img ** 2.2, scale_up)  # undo the sRGB curve roughly: linear z / 8 as shown


def median(x):
    return float(np.median(np.array(x)))


def loadavg():
    try:
        with open("/proc/loadavg") as f:
            return f.read().strip()
    except OSError:
        return None


def suite(args):
    import mitsuba as mi

    mi.set_variant("scalar_rgb")  # this process only reads and writes images; workers render
    work = os.path.join(args.work, "suite")
    os.makedirs(work, exist_ok=True)
    w = lambda name: os.path.join(work, name)
    names = [n for n in args.scenes.split(",") if n]
    bad = [n for n in names if n not in SUITE_SCENES]
    if bad:
        sys.exit(f"unknown scene(s) {bad}: choose from {SUITE_SCENES}")
    if not os.path.exists(args.prt):
        sys.exit(f"no prt binary at {args.prt} (--prt)")
    write_env(mi, work, args.upsample, SUITE_UPSAMPLE_NAME)
    write_suite_meshes(work)
    specs = suite_specs(work)
    R = args.repeats
    report = {"spp": args.spp, "repeats": R, "size": [args.width, args.height], "prt": args.prt,
              "reference": f"llvm_ad_rgb, {args.ref_factor} passes × {args.spp} spp, scene in canonical placement",
              "env_upsample_for_mitsuba": args.upsample, "loadavg_start": loadavg(), "scenes": {}}
    t_start = time.time()
    for name in names:
        spec = specs[name]
        print(f"[{name}] {spec['what']} (load {loadavg()})", file=sys.stderr, flush=True)
        r = {"what": spec["what"], "bounces": spec["bounces"], "placement": spec["placement"],
             "loadavg_before": loadavg()}
        desc = mitsuba_desc(spec, work, args)
        desc_canon = mitsuba_desc(spec, work, args, canonical=True)
        r["triangles"] = int(sum(len(read_obj(s["filename"])[1]) for s in desc["shapes"]))
        ref, ref_var, r["reference"] = suite_reference(desc_canon, args, work, name + "_canonical")
        native_differs = desc != desc_canon
        if native_differs:
            nref, nref_var, r["reference_native"] = suite_reference(desc, args, work, name + "_native", 2000)

        # prt: whole-process wall time, seeds 0..R-1.
        write_prt_toml(w(f"{name}.toml"), spec, args)
        walls = []
        for seed in range(R):
            cmd = [args.prt, "render", w(f"{name}.toml"), "--spp", str(args.spp), "--bounces",
                   str(spec["bounces"]), "--seed", str(seed), "--aovs", "--quiet", "--out", w(f"{name}_prt_s{seed}.exr")]
            t0 = time.perf_counter()
            run = subprocess.run(cmd, capture_output=True, text=True)
            walls.append(time.perf_counter() - t0)
            if run.returncode != 0:
                sys.exit(f"prt render failed on {name}: {run.stderr}")
            if run.stderr.strip():
                r.setdefault("prt_stderr", run.stderr.strip()[-2000:])
        ch = read_exr_channels(mi, w(f"{name}_prt_s0.exr"))
        prt_img = np.stack([ch["R"], ch["G"], ch["B"]], axis=-1)
        prt_var = np.stack([ch["variance.R"], ch["variance.G"], ch["variance.B"]], axis=-1)
        surface2 = ch["depth.Z"] != 0.0
        alb = np.stack([ch["albedo.R"], ch["albedo.G"], ch["albedo.B"]], axis=-1)
        part2 = surface2 & (np.abs(alb - np.array(SUITE_MATERIALS["floor"]["albedo"])).max(axis=-1) > 1e-3)
        surface = surface2[..., None].repeat(3, axis=-1)
        masks = {"all": np.ones_like(surface), "surface": surface, "background": ~surface}

        # Mitsuba: scalar_rgb (no warm-up: nothing to compile) and llvm_ad_rgb (one warm-up render).
        mits = {}
        for variant, warm in (("scalar_rgb", None), ("llvm_ad_rgb", 100)):
            outs = [w(f"{name}_{variant}_s{seed}.npy") for seed in range(R)]
            res = run_worker({"variant": variant, "mode": "timed", "spp": args.spp, "desc": desc,
                              "seeds": list(range(R)), "outs": outs, "warmup_seed": warm}, work, f"{name}_{variant}")
            imgs = [np.load(p).astype(np.float64) for p in outs]
            var1 = np.var(np.stack(imgs), axis=0, ddof=1) if R >= 2 else None  # one render's pixel variance
            mits[variant] = {"img": imgs[0], "imgs": imgs, "var": var1, "res": res}
        r["seconds"] = {"prt_wall": median(walls), "prt_wall_all": walls}
        for v in mits:
            r["seconds"][v] = median(mits[v]["res"]["seconds"])
            r["seconds"][v + "_all"] = mits[v]["res"]["seconds"]
            r["seconds"][v + "_first"] = mits[v]["res"]["first_seconds"]
            r["seconds"][v + "_scene_load"] = mits[v]["res"]["load_seconds"]

        # Errors against the reference and the cost figure of merit.
        images = {"prt": prt_img, "scalar_rgb": mits["scalar_rgb"]["img"], "llvm_ad_rgb": mits["llvm_ad_rgb"]["img"]}
        secs = {"prt": r["seconds"]["prt_wall"], "scalar_rgb": r["seconds"]["scalar_rgb"],
                "llvm_ad_rgb": r["seconds"]["llvm_ad_rgb"]}
        r["rel_l2"], r["rel_l2_ref_noise_removed"], r["cost"] = {}, {}, {}
        for k, img in images.items():
            r["rel_l2"][k], r["rel_l2_ref_noise_removed"][k], r["cost"][k] = {}, {}, {}
            for m in ("all", "surface"):
                e = rel_l2(img, ref, masks[m])
                ref_part = float(np.sum(ref_var[masks[m]]) / np.sum(ref[masks[m]] ** 2))
                r["rel_l2"][k][m] = e
                r["rel_l2_ref_noise_removed"][k][m] = float(np.sqrt(max(e * e - ref_part, 0.0)))
                r["cost"][k][m] = secs[k] * e * e
        r["cost_ratio"] = {f"prt/{v}": {m: r["cost"]["prt"][m] / r["cost"][v][m] for m in ("all", "surface")}
                           for v in ("scalar_rgb", "llvm_ad_rgb")}
        if native_differs:
            r["rel_l2_vs_native_reference"] = {k: {m: rel_l2(img, nref, masks[m]) for m in ("all", "surface")}
                                               for k, img in images.items()}

        # Bias checks (noise-aware): prt vs the reference; each Mitsuba variant vs the reference;
        # the single-scene statistic (prt vs the mean of two scalar_rgb renders).
        r["bias"] = {"prt_vs_reference": {m: bias_stats(prt_img, prt_var, ref, ref_var, masks[m]) for m in masks}}
        for v in mits:
            if mits[v]["var"] is not None:
                r["bias"][f"{v}_vs_reference"] = {m: bias_stats(mits[v]["img"], mits[v]["var"], ref, ref_var, masks[m])
                                                  for m in masks}
        if R >= 2:
            m0, m1 = mits["scalar_rgb"]["imgs"][:2]
            r["bias"]["prt_vs_scalar_pair"] = {m: bias_stats(prt_img, prt_var, 0.5 * (m0 + m1),
                                                             np.full(m0.shape, float(np.mean(((m0 - m1) ** 2)[masks[m]]) / 4.0)),
                                                             masks[m]) for m in masks}
        if native_differs:
            r["native_reference_rel_l2"] = {m: rel_l2(nref, ref, masks[m]) for m in ("all", "surface")}
            r["bias"]["native_reference_vs_reference"] = {m: bias_stats(nref, nref_var, ref, ref_var, masks[m])
                                                          for m in masks}
        # Where: groups of pixels beyond 5 standard errors.
        r["outliers_prt_vs_reference"] = outlier_clusters(prt_img, prt_var, ref, ref_var, part2, surface2)
        z_png(w(f"{name}_z_prt_vs_ref.png"), prt_img, prt_var, ref, ref_var)
        write_png(w(f"{name}_prt.png"), prt_img)
        write_png(w(f"{name}_ref.png"), ref)
        write_png(w(f"{name}_llvm.png"), mits["llvm_ad_rgb"]["img"])
        if native_differs:
            r["outliers_native_reference_vs_reference"] = outlier_clusters(nref, nref_var, ref, ref_var, part2, surface2)
            r["outliers_prt_vs_native_reference"] = outlier_clusters(prt_img, prt_var, nref, nref_var, part2, surface2)
            z_png(w(f"{name}_z_native_vs_ref.png"), nref, nref_var, ref, ref_var)
            write_png(w(f"{name}_ref_native.png"), nref)
        r["loadavg_after"] = loadavg()
        report["scenes"][name] = r
        with open(w("suite.json"), "w") as f:  # written after every scene: a partial run is kept
            json.dump(report, f, indent=2)
    report["loadavg_end"] = loadavg()
    report["total_seconds"] = time.time() - t_start
    with open(w("suite.json"), "w") as f:
        json.dump(report, f, indent=2)
    print(suite_table(report))
    print(f"\nwritten: {w('suite.json')}  (load average start: {report['loadavg_start']}; "
          f"end: {report['loadavg_end']}; {report['total_seconds'] / 60:.1f} min)")


def suite_table(report):
    f2 = lambda x: f"{x:.2f}"
    pct = lambda x: f"{100 * x:.2f}%"
    lines = [
        f"spp {report['spp']}, {report['size'][0]}×{report['size'][1]}, median of {report['repeats']}; "
        f"reference: {report['reference']}. relL2 as all / surface pixels; cost = s × relL2²; "
        "cost ratio < 1: prt is cheaper.",
        "",
        "| scene | tris | B | prt wall s | scalar s | llvm s (first) | relL2 prt | relL2 scalar | relL2 llvm "
        "| cost prt/scalar | cost prt/llvm |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, r in report["scenes"].items():
        s, e, c = r["seconds"], r["rel_l2"], r["cost_ratio"]
        el = lambda k: f"{pct(e[k]['all'])} / {pct(e[k]['surface'])}"
        cr = lambda k: f"{f2(c[k]['all'])} / {f2(c[k]['surface'])}"
        lines.append(f"| {name} | {r['triangles']} | {r['bounces']} | {f2(s['prt_wall'])} | {f2(s['scalar_rgb'])} "
                     f"| {f2(s['llvm_ad_rgb'])} ({f2(s['llvm_ad_rgb_first'])}) | {el('prt')} | {el('scalar_rgb')} "
                     f"| {el('llvm_ad_rgb')} | {cr('prt/scalar_rgb')} | {cr('prt/llvm_ad_rgb')} |")
    lines += [
        "",
        "Bias against the reference (surface pixels): mse_ratio ≈ 1 and |z| ≲ 3 mean noise only; "
        "'px>5σ' counts surface pixels whose difference (channel sum) exceeds 5 standard errors.",
        "",
        "| scene | prt mse_ratio | prt z | prt mean diff | prt px>5σ | scalar mse_ratio / z | llvm mse_ratio / z "
        "| prt vs scalar pair: mse_ratio / z | Mitsuba native-placement ref: relL2 surf, mse_ratio, z |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name, r in report["scenes"].items():
        b = r["bias"]
        p = b["prt_vs_reference"]["surface"]
        mz = lambda k: (f"{f2(b[k]['surface']['mse_ratio'])} / {b[k]['surface']['mean_difference_z']:+.1f}"
                        if k in b else "–")
        nat = "–"
        if "native_reference_vs_reference" in b:
            n = b["native_reference_vs_reference"]["surface"]
            nat = (f"{pct(r['native_reference_rel_l2']['surface'])}, "
                   f"{f2(n['mse_ratio'])}, {n['mean_difference_z']:+.1f}")
        lines.append(f"| {name} | {f2(p['mse_ratio'])} | {p['mean_difference_z']:+.1f} | "
                     f"{100 * p['relative_mean_difference']:+.3f}% | {r['outliers_prt_vs_reference']['surface_pixels_over']} "
                     f"| {mz('scalar_rgb_vs_reference')} | {mz('llvm_ad_rgb_vs_reference')} | {mz('prt_vs_scalar_pair')} "
                     f"| {nat} |")
    return "\n".join(lines)


if __name__ == "__main__":
    main()
