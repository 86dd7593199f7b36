#!/usr/bin/env python3
"""Render one scene with Mitsuba 3's `path` integrator and with `prt render`; report the
difference against the two renders' own noise.

Setup (once): python3 -m venv tools/.venv && tools/.venv/bin/pip install mitsuba numpy
              (for --suite: tools/requirements-peers.txt, which adds bpy, and libllvm19)
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

Suite mode (`--suite`): prt against the peers a user would pick, in one command, on six scenes
(plus `probe`, a mirror sphere that shows whether the environment lines up in every renderer):
  tools/.venv/bin/python tools/mitsuba_compare.py --suite [--spp 1024] [--table FILE.md]
      [--prt PATH] [--prt-sampler replicas|single] [--prt-env-sampling per-normal|compensated|luminance]
      [--prt-split-lobes delta|mirror|none|all] [--timing-rounds N]
      [--scenes sphere,bunny_floor,mirror,far,millimetre,teapot] [--ref-factor 16]
      [--peers llvm_independent,llvm_multijitter,llvm_ldsampler,cycles]
- peers: Mitsuba 3 `llvm_ad_rgb` with its `independent`, `multijitter` and `ldsampler` samplers
  (`scalar_<sampler>` too, on request) and Blender Cycles through bpy (tools/cycles_render.py:
  CPU, Tabulated Sobol, no denoiser, no clamping, no adaptive sampling, box filter of one
  pixel, light tree off and light threshold 0, filter glossy 0, caustics on, bump-map
  correction and shadow-terminator offsets off, the map with `Closest` lookup; the defaults it
  changed are listed in the output). Setup for the peers: tools/requirements-peers.txt
  (`apt-get install -y libllvm19`; the LLVM library is found at Debian's path or through
  $DRJIT_LIBLLVM_PATH).
- scenes: `sphere` (Lambert, 0 bounces), `bunny_floor` (full-res bunny 1 tall on a floor, 1),
  `mirror` (teapot with our `mirror` material on a floor, 2; in Mitsuba a `blendbsdf` of
  `diffuse` albedo/(1−w) and a `conductor` "none" of reflectance specular/w, w = s/(a+s); in
  Cycles Diffuse + Glossy of roughness 0), `far` (bunny_floor translated by (577, 577, 577),
  camera too), `millimetre` (teapot 1 mm wide resting exactly on a ±3 m two-triangle floor, 1),
  `teapot` (rotated by prt's `rotate` key, the peers get the same T·Rz·Ry·Rx·S matrix, 1). All
  Mitsuba BSDFs are `twosided` (prt shades back faces as front faces; so does Cycles);
  perspective near_clip scales with the scene.
- timing, render only for every method, mean of the two timed renders (seeds 0 and 1, prt's
  without AOVs, which come from one more untimed render): prt's
  own render time (it prints it; scene loading and BVH build excluded; the whole process's
  wall time is in the JSON); Mitsuba `mi.render` after one warm-up render of the same sampler
  (JIT tracing + compilation excluded, reported as "first"; scene loading excluded), each
  variant in its own process; Cycles a render after a 1-spp warm-up with persistent data (scene
  sync and BVH build excluded; Cycles' own render/sync times from its EXR are in the JSON).
  With `--timing-rounds N`, N more rounds per scene alternate one prt render and one render
  of the fastest llvm sampler inside that sampler's Mitsuba process (after its warm-up): each
  round's two renders see about the same machine, so the median of the rounds' time-per-sample
  ratios is not moved by a drift between prt's runs and Mitsuba's (an extra table column).
- error: each method renders seeds 0 and 1; E‖X₁ − X₂‖² = 2 Var, so one render's error is
  err = sqrt(mean((X₁ − X₂)²)/2) / RMS(reference) on surface pixels (prt depth AOV ≠ 0). The
  reference (llvm_ad_rgb, --ref-factor passes of --spp, cached in <work>/suite/refs by
  content, rendered with the scene in *canonical placement*, translation removed, scale 1) only
  gives the norm, so err stays right where a method is less noisy than the reference. cost =
  seconds × err² (time at equal error); cost ratios prt / each peer and prt / the best peer;
  time per sample prt / the fastest llvm sampler. tools/test_peer_compare.py tests these
  functions on synthetic data (numpy only).
- bias check: the mean of each method's two renders against the reference (mse_ratio and z of
  the single-scene mode, per-pixel variance from the two seeds); the background pixels of each
  peer against prt's (a turned or mirrored map shows as tens of %); for `far` and
  `millimetre` the native-placement Mitsuba reference too (Mitsuba's ray offset
  (1 + max|p|)·8.9e-5 changes under translation and scale); prt's pixels beyond 5 standard
  errors grouped into clusters (`outliers_*`).
- output: a Markdown summary table and one table per scene in FILE.md (default
  <work>/suite/suite.md), the same figures in FILE.json, PNG views (`<scene>_side_by_side.png`:
  reference, prt, then each peer) and prt's z map in <work>/suite/.
- The issue-32 table, one run on a quiet machine (nothing else running):
    tools/.venv/bin/python tools/mitsuba_compare.py --suite --spp 1024 --table out/peers.md
  It takes about 15 min on 2 quiet cores (estimate: `teapot` alone took 5.2 min at load 6–7 on
  this shared machine, where Mitsuba ran 2.6× slower than on a quiet one; 64×48 / 64-spp runs
  of two scenes take 30 s). About a third of a first run is the Mitsuba references (16 renders
  of 1024 spp per scene, 16 more for the native placement of `far` and `millimetre`), cached
  by content in out/mitsuba_compare/suite/refs, so a re-run takes about 10 min. A quick end-to-end check: --spp 64 --width 64 --height 48
  --scenes probe,mirror.
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
    ap.add_argument("--prt-sampler", choices=["replicas", "single"], default="replicas",
                    help="prt's pixel sampler (`prt render --sampler`): `replicas` (its default, with "
                         "the image's own noise estimate) or `single` (one Sobol sequence of all the "
                         "samples: lower error per sample, no noise estimate)")
    ap.add_argument("--prt-env-sampling", choices=["per-normal", "compensated", "luminance"],
                    default="per-normal",
                    help="prt's environment sampling density (`prt render --env-sampling`): "
                         "`per-normal` (its default, MIS compensation per shading normal), "
                         "`compensated` (one compensated table) or `luminance`")
    ap.add_argument("--prt-split-lobes", choices=["delta", "mirror", "none", "all"], default="delta",
                    help="prt's lobe splitting (`prt render --split-lobes`): `delta` (its default: "
                         "diffuse-plus-mirror materials follow the mirror ray at every vertex and "
                         "the diffuse lobe as often as a lobe choice takes it), `mirror` (both "
                         "lobes at every such vertex), `none` (one lobe chosen at random, as the "
                         "peers do) or `all`")
    ap.add_argument("--variant", default="scalar_rgb")
    ap.add_argument("--upsample", type=int, default=16,
                    help="nearest-neighbour upsampling of the map for Mitsuba (FACTS.md says ×4; "
                         "more shrinks the bilinear blend zone at texel edges)")
    ap.add_argument("--suite", action="store_true",
                    help="render the six-scene suite with prt and its peers (see 'Suite mode' above)")
    ap.add_argument("--scenes", default=",".join(SUITE_SCENES),
                    help="--suite: comma-separated subset of " + ",".join(SUITE_SCENES + EXTRA_SCENES))
    ap.add_argument("--peers", default=",".join(DEFAULT_PEERS),
                    help="--suite: methods prt is measured against: 'cycles' and <llvm|scalar>_"
                         "<independent|multijitter|ldsampler>")
    ap.add_argument("--table", help="--suite: Markdown output (default <work>/suite/suite.md); the JSON "
                                    "goes next to it with the suffix .json")
    ap.add_argument("--ref-factor", type=int, default=16,
                    help="--suite: the reference is this many llvm_ad_rgb passes of --spp each")
    ap.add_argument("--timing-rounds", type=int, default=0,
                    help="--suite: after each scene's runs, N more rounds alternating one prt render and "
                         "one render of the fastest llvm sampler inside the same Mitsuba process; the "
                         "table adds the median of the per-round time-per-sample ratios (a drift of the "
                         "machine between prt's runs and Mitsuba's cancels in each round)")
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
           "--sampler", args.prt_sampler, "--env-sampling", args.prt_env_sampling,
           "--split-lobes", args.prt_split_lobes, "--aovs", "--quiet",
           "--out", w("ours.exr")]
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
EXTRA_SCENES = ["probe"]  # a mirror sphere: checks that the environment lines up in every renderer
LLVM_LIB = os.path.join(ROOT, "tools", ".venv", "llvm19", "usr", "lib", "x86_64-linux-gnu",
                        "libLLVM.so.19.1")
SYSTEM_LLVM_LIB = "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1"  # apt-get install libllvm19
SUITE_UPSAMPLE_NAME = "env_up.exr"

SUITE_MATERIALS = {
    "clay": {"type": "lambert", "albedo": [0.8, 0.7, 0.6]},
    "floor": {"type": "lambert", "albedo": [0.5, 0.5, 0.5]},
    # grey on purpose: Mitsuba's blend weight w = s / (a + s) is one scalar for all channels.
    "chrome": {"type": "mirror", "albedo": [0.2, 0.2, 0.2], "specular": [0.6, 0.6, 0.6]},
    "probe_chrome": {"type": "mirror", "albedo": [0.05, 0.05, 0.05], "specular": [0.9, 0.9, 0.9]},
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
        "probe": {
            "bounces": 0, "camera": cam([0, 0, 3.6], [0, 0, 0], 40),
            "objects": [obj("sphere.obj", "probe_chrome")],
            "what": "mirror sphere (albedo 0.05 + specular 0.9): the environment's line-up",
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


def build_mitsuba_scene(mi, desc, spp, sampler="independent"):
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
            "sampler": {"type": sampler, "sample_count": spp},
        },
        "env": {"type": "envmap", "filename": desc["env"]},
    }
    for k, sh in enumerate(desc["shapes"]):
        d[f"shape{k}"] = {"type": "obj", "filename": sh["filename"],
                          "to_world": mi.ScalarTransform4f(np.array(sh["to_world"])), "bsdf": sh["bsdf"]}
    return mi.load_dict(d)


def llvm_library():
    """libLLVM for Dr.Jit's LLVM backend: $DRJIT_LIBLLVM_PATH, else Debian's libllvm19, else a
    copy unpacked into the venv (older set-up)."""
    for path in (os.environ.get("DRJIT_LIBLLVM_PATH"), SYSTEM_LLVM_LIB, LLVM_LIB):
        if path and os.path.exists(path):
            return path
    return None


def mitsuba_worker(job_path):
    """Runs in its own process (one Mitsuba variant per process)."""
    with open(job_path) as f:
        job = json.load(f)
    if job["variant"].startswith("llvm") and llvm_library():
        os.environ["DRJIT_LIBLLVM_PATH"] = llvm_library()
    import mitsuba as mi

    mi.set_variant(job["variant"])
    spp = job["spp"]
    out = {"variant": job["variant"], "mitsuba": mi.__version__}

    def render(scene, seed):
        t = time.perf_counter()
        img = mi.render(scene, seed=seed, spp=spp)
        a = np.array(img, dtype=np.float32)[..., :3]  # forces evaluation of a JIT variant
        return a, time.perf_counter() - t

    if job["mode"] == "paired":
        # Load and warm up once, then alternate: one prt render (its own render time), one
        # Mitsuba render. Mitsuba idles while prt runs, so each has the machine to itself.
        scene = build_mitsuba_scene(mi, job["desc"], spp, job["sampler"])
        out["sample_count"] = int(scene.sensors()[0].sampler().sample_count())
        render(scene, job["warmup_seed"])
        out["rounds"] = []
        for k in range(job["rounds"]):
            run = subprocess.run(job["prt_cmd"], capture_output=True, text=True)
            if run.returncode != 0:
                raise SystemExit(f"prt render failed: {run.stderr[-2000:]}")
            _, secs = render(scene, k)
            out["rounds"].append([parse_prt_render_seconds(run.stderr), secs])
    elif job["mode"] == "timed":
        # Per sampler: load, one warm-up render (JIT tracing + compilation for llvm), then the
        # timed renders. Only mi.render is timed: scene loading and the warm-up are excluded.
        out["samplers"] = {}
        for sampler in job["samplers"]:
            t = time.perf_counter()
            scene = build_mitsuba_scene(mi, job["desc"], spp, sampler)
            r = {"load_seconds": time.perf_counter() - t,
                 "sample_count": int(scene.sensors()[0].sampler().sample_count())}
            if job.get("warmup_seed") is not None:
                _, r["first_seconds"] = render(scene, job["warmup_seed"])
            r["seconds"] = []
            for seed, path in zip(job["seeds"], job["outs"][sampler]):
                a, secs = render(scene, seed)
                r["seconds"].append(secs)
                np.save(path, a)
            r.setdefault("first_seconds", r["seconds"][0])
            out["samplers"][sampler] = r
    else:  # reference: the mean of passes, with the variance of that mean from their spread
        scene = build_mitsuba_scene(mi, job["desc"], spp)
        s1 = s2 = 0.0
        out["seconds"] = []
        for seed in job["seeds"]:
            a, secs = render(scene, seed)
            out["seconds"].append(secs)
            a = a.astype(np.float64)
            s1, s2 = s1 + a, s2 + a * a
        n = len(job["seeds"])
        mean = s1 / n
        var_pass = np.maximum(s2 / n - mean * mean, 0.0) * n / (n - 1)
        np.savez(job["out"], mean=mean, var_of_mean=var_pass / n)
    with open(job["result"], "w") as f:
        json.dump(out, f)


def run_worker(job, work, tag, script=None):
    """Runs a Mitsuba worker (this file, --worker) or another script (`script JOB.json`) in its
    own process; returns its result JSON."""
    path = os.path.join(work, f"job_{tag}.json")
    job["result"] = os.path.join(work, f"job_{tag}.result.json")
    with open(path, "w") as f:
        json.dump(job, f)
    cmd = [sys.executable, os.path.abspath(__file__), "--worker", path] if script is None else \
        [sys.executable, script, path]
    run = subprocess.run(cmd, capture_output=True, text=True)
    if run.returncode != 0:
        sys.exit(f"worker {tag} failed ({run.returncode}):\n{run.stdout[-3000:]}\n{run.stderr[-3000:]}")
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


def host_simd(cpuinfo_text):
    """The CPU model and the widest vector instruction set its flags list, from the text of
    /proc/cpuinfo: Dr.Jit's LLVM backend compiles for the host, so its lanes per instruction
    (16 f32 with AVX-512, 8 with AVX2) and hence the time-per-sample ratio depend on it."""
    model, flags = None, set()
    for line in cpuinfo_text.splitlines():
        key, _, value = line.partition(":")
        key = key.strip()
        if key == "model name" and model is None:
            model = value.strip()
        elif key == "flags" and not flags:
            flags = set(value.split())
    simd = next((name for flag, name in (("avx512f", "AVX-512"), ("avx2", "AVX2"), ("avx", "AVX"),
                                         ("sse2", "SSE2")) if flag in flags), None)
    return {"model": model, "simd": simd, "fma": "fma" in flags}


def host():
    """This machine's CPU (`host_simd` of /proc/cpuinfo) and core count, for the report."""
    try:
        with open("/proc/cpuinfo") as f:
            text = f.read()
    except OSError:  # not Linux: model and SIMD unknown
        text = ""
    return {**host_simd(text), "cores": os.cpu_count()}


def loadavg():
    try:
        with open("/proc/loadavg") as f:
            return f.read().strip()
    except OSError:
        return None


# Methods of the suite: prt and its peers. A Mitsuba peer is "<variant>_<sampler>".
DEFAULT_PEERS = ["llvm_independent", "llvm_multijitter", "llvm_ldsampler", "cycles"]
MITSUBA_VARIANTS = {"llvm": "llvm_ad_rgb", "scalar": "scalar_rgb"}
MITSUBA_SAMPLERS = ["independent", "multijitter", "ldsampler"]
SEEDS = (0, 1)  # two independent renders per method: its error comes from their difference
CYCLES_SCRIPT = os.path.join(ROOT, "tools", "cycles_render.py")


def parse_peers(text):
    peers = [p for p in text.split(",") if p]
    for p in peers:
        v, _, smp = p.partition("_")
        if p != "cycles" and (v not in MITSUBA_VARIANTS or smp not in MITSUBA_SAMPLERS):
            raise ValueError(f"unknown peer {p!r}: 'cycles' or <{'|'.join(MITSUBA_VARIANTS)}>_"
                             f"<{'|'.join(MITSUBA_SAMPLERS)}>")
    return peers


def two_seed_error(x1, x2, ref, mask):
    """One render's relative RMS error from two renders with independent seeds:
    err = sqrt(mean((x1 − x2)²) / 2) / sqrt(mean(ref²)) over `mask`. For unbiased renders with
    the same expectation E(x1 − x2)² = 2 Var per pixel, so mean((x1 − x2)²)/2 estimates the mean
    variance of one render; the reference enters only through its norm, so the figure stays
    right when a method's error is below the reference's own noise (where a distance to the
    reference measures the reference). A bias does not show here: bias_stats checks for it."""
    d = (x1 - x2)[mask]
    return float(np.sqrt(np.mean(d * d) / 2.0 / np.mean(ref[mask] ** 2)))


def cost_at_equal_error(seconds, err):
    """time × err²: the time to reach a common error, up to a constant, since err² ∝ 1/samples."""
    return seconds * err * err


def cost_ratios(costs, me="prt"):
    """`me`'s cost over each other method's, and over the cheapest other's: (ratios, best, ratio)."""
    peers = {k: v for k, v in costs.items() if k != me}
    ratios = {k: costs[me] / v for k, v in peers.items()}
    best = min(peers, key=peers.get)
    return ratios, best, costs[me] / peers[best]


def parse_prt_render_seconds(stderr):
    """`prt render` prints `rendered W×H at N spp, … in S s (…)`: S is the render alone (scene
    loading and BVH build excluded)."""
    import re
    m = re.search(r"^rendered .* in ([0-9.]+) s \(", stderr, re.M)
    if not m:
        raise ValueError(f"no 'rendered … in S s' line in prt's output:\n{stderr[-2000:]}")
    return float(m.group(1))


def prt_render_cmd(args, toml, spec, seed, exr):
    """The `prt render` command of the suite's timed renders."""
    return [args.prt, "render", toml, "--spp", str(args.spp), "--bounces", str(spec["bounces"]),
            "--seed", str(seed), "--sampler", args.prt_sampler, "--env-sampling", args.prt_env_sampling,
            "--split-lobes", args.prt_split_lobes, "--quiet", "--out", exr]


def paired_ratios(rounds, prt_spp, mitsuba_samples):
    """Time per sample prt / Mitsuba of each alternated round (`rounds`: [prt s, Mitsuba s]), and
    their median (the figure a drifting machine disturbs least: both renders of a round see
    about the same machine)."""
    ratios = [(p / prt_spp) / (m / mitsuba_samples) for p, m in rounds]
    return ratios, float(np.median(ratios)) if ratios else None


def run_paired_timing(args, work, name, spec, desc, peer):
    """`args.timing_rounds` rounds of one prt render (seed 0, both threads) and one render of
    Mitsuba `peer` (an llvm sampler), alternated inside one Mitsuba process after its warm-up."""
    w = lambda f: os.path.join(work, f)
    variant, sampler = MITSUBA_VARIANTS[peer.partition("_")[0]], peer.partition("_")[2]
    cmd = prt_render_cmd(args, w(f"{name}.toml"), spec, SEEDS[0], w(f"{name}_prt_paired.exr"))
    res = run_worker({"variant": variant, "mode": "paired", "spp": args.spp, "desc": desc,
                      "sampler": sampler, "rounds": args.timing_rounds, "prt_cmd": cmd, "warmup_seed": 100},
                     work, f"{name}_paired")
    ratios, median = paired_ratios(res["rounds"], args.spp, res["sample_count"])
    return {"peer": peer, "rounds": res["rounds"], "ratios": ratios, "median": median}


def run_prt(args, work, name, spec):
    """prt at seeds 0 and 1: images, render seconds, whole-process seconds, seed 0's AOVs.
    The timed renders write no AOVs (as a user who does not need them renders; they cost about
    2 % of the time); the AOVs come from one more, untimed render of seed 0 with `--aovs`, whose
    image is the same (AOVs draw no samples)."""
    import mitsuba as mi
    w = lambda f: os.path.join(work, f)
    write_prt_toml(w(f"{name}.toml"), spec, args)
    out = {"imgs": [], "seconds": [], "wall": []}

    def render(seed, exr, aovs):
        cmd = prt_render_cmd(args, w(f"{name}.toml"), spec, seed, exr) + (["--aovs"] if aovs else [])
        t0 = time.perf_counter()
        run = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if run.returncode != 0:
            sys.exit(f"prt render failed on {name}: {run.stderr}")
        warnings = [l for l in run.stderr.splitlines() if l.startswith("warning")]
        if warnings:
            out["warnings"] = warnings
        return run, wall, read_exr_channels(mi, exr)

    for seed in SEEDS:
        run, wall, ch = render(seed, w(f"{name}_prt_s{seed}.exr"), aovs=False)
        out["wall"].append(wall)
        out["seconds"].append(parse_prt_render_seconds(run.stderr))
        out["imgs"].append(np.stack([ch["R"], ch["G"], ch["B"]], axis=-1))
    _, _, ch = render(SEEDS[0], w(f"{name}_prt_s{SEEDS[0]}_aovs.exr"), aovs=True)
    if not np.array_equal(np.stack([ch["R"], ch["G"], ch["B"]], axis=-1), out["imgs"][0]):
        sys.exit(f"prt's image with --aovs differs from the one without on {name}")
    out["aov"] = ch
    return out


def run_mitsuba_peers(args, work, name, desc, peers):
    """One worker process per Mitsuba variant, rendering each of its samplers at seeds 0 and 1
    after one warm-up render; returns {peer: {imgs, seconds, ...}}."""
    out = {}
    for vshort, variant in MITSUBA_VARIANTS.items():
        samplers = [p.partition("_")[2] for p in peers if p.partition("_")[0] == vshort]
        if not samplers:
            continue
        outs = {smp: [os.path.join(work, f"{name}_{vshort}_{smp}_s{seed}.npy") for seed in SEEDS]
                for smp in samplers}
        res = run_worker({"variant": variant, "mode": "timed", "spp": args.spp, "desc": desc,
                          "samplers": samplers, "seeds": list(SEEDS), "outs": outs, "warmup_seed": 100},
                         work, f"{name}_{vshort}")
        for smp in samplers:
            r = res["samplers"][smp]
            out[f"{vshort}_{smp}"] = {
                "imgs": [np.load(p).astype(np.float64) for p in outs[smp]], "seconds": r["seconds"],
                "samples": r["sample_count"], "first_seconds": r["first_seconds"],
                "load_seconds": r["load_seconds"], "version": "Mitsuba " + res["mitsuba"]}
    return out


def run_cycles(args, work, name, spec):
    objs, cam = placed(spec)
    shapes = [{"filename": os.path.join(work, o["mesh"]), "material": o["material"],
               "to_world": object_matrix(o["translate"], o["rotate"], o["scale"]).tolist()} for o in objs]
    outs = [os.path.join(work, f"{name}_cycles_s{seed}.npy") for seed in SEEDS]
    job = {"width": args.width, "height": args.height, "bounces": spec["bounces"], "spp": args.spp,
           "camera": cam, "env": os.path.join(work, CYCLES_ENV_NAME), "shapes": shapes,
           "materials": {o["material"]: SUITE_MATERIALS[o["material"]] for o in objs},
           "seeds": list(SEEDS), "outs": [p[:-4] for p in outs], "warmup_seed": 100}
    res = run_worker(job, work, f"{name}_cycles", script=CYCLES_SCRIPT)
    return {"imgs": [np.load(p).astype(np.float64) for p in outs], "seconds": res["seconds"],
            "samples": res["samples"], "first_seconds": res["warmup_seconds"],
            "load_seconds": res["build_seconds"], "version": "Blender " + res["blender"],
            "changed_defaults": res["changed_defaults"], "cycles_own_times": res["cycles_times"]}


CYCLES_ENV_NAME = "env_cycles.exr"


def write_cycles_env(mi, work):
    """Our 64×32 map with its columns rolled by W/4 (see tools/cycles_render.py): Cycles'
    equirectangular u is ours + 1/4 once our +Y-up axes are turned into Blender's +Z-up."""
    from cycles_render import cycles_env_columns_shift
    small = np.array(mi.Bitmap(os.path.join(work, "env.exr")), dtype=np.float32)[..., :3]
    rolled = np.ascontiguousarray(np.roll(small, cycles_env_columns_shift(small.shape[1]), axis=1))
    mi.Bitmap(rolled).write(os.path.join(work, CYCLES_ENV_NAME))


def method_figures(m, ref, ref_var, masks, spp):
    """Seconds (mean of the timed renders), two-seed error, cost, relL2 and bias of the mean of
    the two renders against the reference, on surface pixels."""
    x1, x2 = m["imgs"]
    surf = masks["surface"]
    mean = 0.5 * (x1 + x2)
    var_mean = (x1 - x2) ** 2 / 4.0  # per pixel: an unbiased estimate of Var((x1 + x2)/2)
    f = {"seconds": float(np.mean(m["seconds"])), "seconds_each": m["seconds"],
         "samples": m.get("samples", spp), "err": two_seed_error(x1, x2, ref, surf)}
    f["seconds_per_sample"] = f["seconds"] / f["samples"]
    f["cost"] = cost_at_equal_error(f["seconds"], f["err"])
    f["rel_l2_mean_vs_reference"] = rel_l2(mean, ref, surf)
    f["bias_vs_reference"] = {k: bias_stats(mean, var_mean, ref, ref_var, masks[k]) for k in masks}
    for k in ("first_seconds", "load_seconds", "version", "changed_defaults", "cycles_own_times"):
        if k in m:
            f[k] = m[k]
    return f


def side_by_side_png(path, images, scale_up=3):
    """Images left to right with a 2-pixel black gap."""
    h = images[0].shape[0]
    gap = np.zeros((h, 2, 3))
    row = []
    for img in images:
        row += [img, gap]
    write_png(path, np.concatenate(row[:-1], axis=1), scale_up)


def suite(args):
    import mitsuba as mi

    mi.set_variant("scalar_rgb")  # this process only reads and writes images; workers render
    sys.path.insert(0, os.path.join(ROOT, "tools"))
    peers = parse_peers(args.peers)
    work = os.path.join(args.work, "suite")
    os.makedirs(work, exist_ok=True)
    w = lambda name: os.path.join(work, name)
    names = [n for n in args.scenes.split(",") if n]
    bad = [n for n in names if n not in SUITE_SCENES + EXTRA_SCENES]
    if bad:
        sys.exit(f"unknown scene(s) {bad}: choose from {SUITE_SCENES + EXTRA_SCENES}")
    if not os.path.exists(args.prt):
        sys.exit(f"no prt binary at {args.prt} (--prt)")
    if any(p.startswith("llvm") for p in peers) and llvm_library() is None:
        sys.exit("llvm_ad_rgb needs libLLVM: apt-get install -y libllvm19 (or set DRJIT_LIBLLVM_PATH)")
    write_env(mi, work, args.upsample, SUITE_UPSAMPLE_NAME)
    if "cycles" in peers:
        write_cycles_env(mi, work)
    write_suite_meshes(work)
    specs = suite_specs(work)
    table = args.table or w("suite.md")
    json_path = os.path.splitext(table)[0] + ".json"
    report = {"spp": args.spp, "seeds": list(SEEDS), "size": [args.width, args.height], "prt": args.prt,
              "prt_sampler": args.prt_sampler, "prt_env_sampling": args.prt_env_sampling,
              "prt_split_lobes": args.prt_split_lobes,
              "peers": peers, "llvm_library": llvm_library(),
              "reference": f"llvm_ad_rgb independent, {args.ref_factor} passes × {args.spp} spp, scene in "
                           "canonical placement",
              "env_upsample_for_mitsuba": args.upsample, "host": host(), "loadavg_start": loadavg(),
              "scenes": {}}
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

        methods = {"prt": run_prt(args, work, name, spec)}
        methods.update(run_mitsuba_peers(args, work, name, desc, peers))
        if "cycles" in peers:
            methods["cycles"] = run_cycles(args, work, name, spec)
        ch = methods["prt"].pop("aov")
        prt_var = np.stack([ch["variance.R"], ch["variance.G"], ch["variance.B"]], axis=-1)
        surface2 = ch["depth.Z"] != 0.0
        alb = np.stack([ch["albedo.R"], ch["albedo.G"], ch["albedo.B"]], axis=-1)
        part2 = surface2 & (np.abs(alb - np.array(SUITE_MATERIALS["floor"]["albedo"])).max(axis=-1) > 1e-3)
        surface = surface2[..., None].repeat(3, axis=-1)
        masks = {"all": np.ones_like(surface), "surface": surface, "background": ~surface}

        r["methods"] = {k: method_figures(m, ref, ref_var, masks, args.spp) for k, m in methods.items()}
        r["methods"]["prt"]["wall_seconds_each"] = methods["prt"]["wall"]
        if "warnings" in methods["prt"]:
            r["prt_warnings"] = methods["prt"]["warnings"]
        # Environment line-up: background pixels show the map directly, so each peer's mean
        # image there should match prt's up to noise and Mitsuba's bilinear blend at texel edges;
        # a turned or mirrored map shows as a difference of order 1.
        prt_mean = 0.5 * sum(methods["prt"]["imgs"])
        for k, m in methods.items():
            if masks["background"].any():
                r["methods"][k]["background_rel_l2_vs_prt"] = rel_l2(0.5 * sum(m["imgs"]), prt_mean,
                                                                     masks["background"])
        costs = {k: f["cost"] for k, f in r["methods"].items()}
        r["cost_ratio"], r["best_peer"], r["cost_ratio_best_peer"] = cost_ratios(costs)
        llvm = [k for k in r["methods"] if k.startswith("llvm_")]
        if llvm:
            fastest = min(llvm, key=lambda k: r["methods"][k]["seconds_per_sample"])
            r["time_per_sample_prt_over_llvm"] = (r["methods"]["prt"]["seconds_per_sample"]
                                                  / r["methods"][fastest]["seconds_per_sample"])
            r["time_per_sample_llvm_sampler"] = fastest
            if args.timing_rounds > 0:
                r["time_per_sample_paired"] = run_paired_timing(args, work, name, spec, desc, fastest)
        if native_differs:
            r["native_reference_rel_l2"] = {m: rel_l2(nref, ref, masks[m]) for m in ("all", "surface")}
            r["bias_native_reference_vs_reference"] = {m: bias_stats(nref, nref_var, ref, ref_var, masks[m])
                                                       for m in masks}
        # Where prt differs: groups of pixels beyond 5 standard errors (prt's variance AOV).
        prt_img = methods["prt"]["imgs"][0]
        r["outliers_prt_vs_reference"] = outlier_clusters(prt_img, prt_var, ref, ref_var, part2, surface2)
        z_png(w(f"{name}_z_prt_vs_ref.png"), prt_img, prt_var, ref, ref_var)
        write_png(w(f"{name}_ref.png"), ref)
        for k, m in methods.items():
            write_png(w(f"{name}_{k}.png"), m["imgs"][0])
        side_by_side_png(w(f"{name}_side_by_side.png"), [ref] + [m["imgs"][0] for m in methods.values()])
        r["side_by_side_order"] = ["reference"] + list(methods)
        r["loadavg_after"] = loadavg()
        report["scenes"][name] = r
        with open(json_path, "w") as f:  # written after every scene: a partial run is kept
            json.dump(report, f, indent=2)
    report["loadavg_end"] = loadavg()
    report["total_seconds"] = time.time() - t_start
    with open(json_path, "w") as f:
        json.dump(report, f, indent=2)
    text = suite_table(report)
    with open(table, "w") as f:
        f.write(text + "\n")
    print(text)
    print(f"\nwritten: {table} and {json_path}  (load average start: {report['loadavg_start']}; "
          f"end: {report['loadavg_end']}; {report['total_seconds'] / 60:.1f} min)")


def host_line(h):
    """The table's note on the host: time per sample against Mitsuba `llvm` depends on its
    vector width."""
    if not h:
        return ""
    return (f" Host: {h.get('model') or 'unknown CPU'}, {h.get('cores')} cores, widest SIMD "
            f"{h.get('simd') or 'unknown'} (Dr.Jit's LLVM kernels use the host's full width).")


def peer_label(k):
    return {"prt": "prt", "cycles": "Cycles"}.get(k, k.replace("_", " "))


def suite_table(report):
    f2 = lambda x: f"{x:.2f}"
    pct = lambda x: f"{100 * x:.2f}%"
    scenes = report["scenes"]
    methods = list(next(iter(scenes.values()))["methods"]) if scenes else []
    peers = [k for k in methods if k != "prt"]
    paired = any("time_per_sample_paired" in r for r in scenes.values())
    lines = [
        f"{report['spp']} spp, {report['size'][0]}×{report['size'][1]}, seeds {report['seeds']}; reference: "
        f"{report['reference']}; prt's sampler: `--sampler {report.get('prt_sampler', 'replicas')}"
        f" --env-sampling {report.get('prt_env_sampling', 'luminance')}"
        f" --split-lobes {report.get('prt_split_lobes', 'none')}`. "
        "s = seconds of one render, render only for every method (mean of the two "
        "seeds' renders; prt: its own render time, BVH build excluded; Mitsuba: `mi.render` after a warm-up "
        "render of the same sampler, i.e. JIT compilation and scene loading excluded; Cycles: a render after "
        "a 1-spp warm-up with persistent data, i.e. BVH build and scene sync excluded). err = one render's "
        "relative RMS error on surface pixels from its two seeds, sqrt(mean((X₁−X₂)²)/2)/RMS(reference). "
        "cost = s × err² (time at equal error, up to a constant); cost ratio < 1: prt is cheaper."
        + host_line(report.get("host")),
        "",
        "| scene | B | " + " | ".join(f"{peer_label(k)} s / err" for k in methods)
        + " | time/sample prt/llvm |" + (" time/sample prt/llvm, alternated rounds (median) |" if paired else "")
        + " " + " | ".join(f"cost prt/{peer_label(k)}" for k in peers)
        + " | cost prt/best peer |",
        "|---|---|" + "---|" * (len(methods) + 1 + int(paired) + len(peers) + 1),
    ]
    for name, r in scenes.items():
        mf = r["methods"]
        tps = f2(r["time_per_sample_prt_over_llvm"]) if "time_per_sample_prt_over_llvm" in r else "–"
        if paired:
            pr = r.get("time_per_sample_paired")
            tps += f" | {f2(pr['median']) if pr and pr['median'] is not None else '–'}"
        lines.append(f"| {name} | {r['bounces']} | "
                     + " | ".join(f"{f2(mf[k]['seconds'])} / {mf[k]['err']:.4f}" for k in methods)
                     + f" | {tps} | " + " | ".join(f2(r["cost_ratio"][k]) for k in peers)
                     + f" | **{f2(r['cost_ratio_best_peer'])}** ({peer_label(r['best_peer'])}) |")
    for name, r in scenes.items():
        mf = r["methods"]
        lines += [
            "", f"### {name}: {r['what']} ({r['triangles']} triangles, {r['bounces']} bounces)", "",
            "| method | samples | s | s first render | err | cost s×err² | cost prt/this | relL2 mean-vs-ref "
            "| bias: mse_ratio / z (surface) | background relL2 vs prt |",
            "|---|---|---|---|---|---|---|---|---|---|",
        ]
        for k in methods:
            f = mf[k]
            b = f["bias_vs_reference"]["surface"]
            bg = f.get("background_rel_l2_vs_prt")
            lines.append(
                f"| {peer_label(k)} | {f['samples']} | {f2(f['seconds'])} | "
                f"{f2(f['first_seconds']) if 'first_seconds' in f else '–'} | {f['err']:.4f} | {f['cost']:.3g} | "
                f"{f2(r['cost_ratio'][k]) if k in r['cost_ratio'] else '–'} | {pct(f['rel_l2_mean_vs_reference'])} | "
                f"{f2(b['mse_ratio'])} / {b['mean_difference_z']:+.1f} | {pct(bg) if bg is not None else '–'} |")
        extra = []
        if "time_per_sample_prt_over_llvm" in r:
            extra.append(f"time per sample prt / {r['time_per_sample_llvm_sampler']}: "
                         f"{f2(r['time_per_sample_prt_over_llvm'])}")
        if r.get("time_per_sample_paired"):
            pr = r["time_per_sample_paired"]
            extra.append(f"in {len(pr['rounds'])} alternated rounds against {peer_label(pr['peer'])} "
                         f"(prt s / Mitsuba s: {', '.join(f'{a:.2f} / {b:.2f}' for a, b in pr['rounds'])}): "
                         f"median {f2(pr['median'])}")
        extra.append(f"cost prt / best peer ({peer_label(r['best_peer'])}): {f2(r['cost_ratio_best_peer'])}")
        if "native_reference_rel_l2" in r:
            extra.append(f"Mitsuba's native-placement reference is {pct(r['native_reference_rel_l2']['surface'])} "
                         "(surface relL2) off the canonical one")
        lines += ["", "; ".join(extra) + "."]
    lines += [
        "", "Notes:",
        "- bias: the mean of the two seeds against the reference, mse_ratio = MSE / expected MSE from both "
        "images' noise (≈ 1 and |z| ≲ 3 when they differ by noise only; the two-seed variance per pixel).",
        "- background relL2 vs prt: pixels that show the map directly; a misaligned environment shows as "
        "tens of %. Mitsuba's envmap is bilinear (its map is upsampled by nearest neighbour to keep the blend "
        "near texel edges), Cycles' lookup is `Closest` like prt's.",
        "- first render: Mitsuba's warm-up (JIT tracing + compilation of that sampler's kernels, or Dr.Jit's "
        "on-disk cache); Cycles' 1-spp warm-up (scene sync, BVH build).",
    ]
    changed = next((r["methods"]["cycles"].get("changed_defaults") for r in scenes.values()
                    if "cycles" in r["methods"]), None)
    if changed is not None:
        ver = next(r["methods"]["cycles"]["version"] for r in scenes.values() if "cycles" in r["methods"])
        lines += [f"- Cycles ({ver}, CPU): defaults switched off or changed, read back from Blender: "
                  + "; ".join(changed) + ". Also: bounces = prt's (max/diffuse/glossy/transmission); "
                  "box filter of width 1 px = the pixel's square (Cycles samples [−w/2, w/2]² around the "
                  "pixel centre; its minimum width 0.01 would point-sample pixel centres); the map with "
                  "`Closest` interpolation, rolled by W/4 for Blender's +Z-up axes."]
    return "\n".join(lines)


if __name__ == "__main__":
    main()
