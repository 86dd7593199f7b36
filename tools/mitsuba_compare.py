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


def write_obj_with_normals(path, verts, faces):
    tri = verts[faces]
    face_n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])  # length = 2·area
    normals = np.zeros_like(verts)
    for k in range(3):
        np.add.at(normals, faces[:, k], face_n)
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-30)
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
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--bounces", type=int, default=1)
    ap.add_argument("--width", type=int, default=160)
    ap.add_argument("--height", type=int, default=120)
    ap.add_argument("--work", default=os.path.join(ROOT, "out", "mitsuba_compare"))
    ap.add_argument("--prt", default=os.path.join(ROOT, "target", "release", "prt"))
    ap.add_argument("--variant", default="scalar_rgb")
    ap.add_argument("--upsample", type=int, default=16,
                    help="nearest-neighbour upsampling of the map for Mitsuba (FACTS.md says ×4; "
                         "more shrinks the bilinear blend zone at texel edges)")
    args = ap.parse_args()

    import mitsuba as mi

    mi.set_variant(args.variant)
    os.makedirs(args.work, exist_ok=True)
    w = lambda name: os.path.join(args.work, name)

    # Environment: courtyard box-averaged to 64×32, negatives clamped (as our loader does).
    src = np.array(mi.Bitmap(os.path.join(ROOT, "scenes", "maps", "courtyard.exr")).convert(
        mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32, srgb_gamma=False), dtype=np.float64)
    src = np.maximum(src, 0.0)
    h, wd = src.shape[:2]
    small = src.reshape(32, h // 32, 64, wd // 64, 3).mean(axis=(1, 3)).astype(np.float32)
    mi.Bitmap(small).write(w("env.exr"))
    mi.Bitmap(np.ascontiguousarray(np.repeat(np.repeat(small, args.upsample, axis=0), args.upsample, axis=1))).write(w("env_x4.exr"))

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


if __name__ == "__main__":
    main()
