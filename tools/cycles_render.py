#!/usr/bin/env python3
"""Blender Cycles column of tools/mitsuba_compare.py --suite: renders one suite scene with
Cycles through `bpy` (Blender as a Python module), set up to compute the same image in
expectation as `prt render` and Mitsuba 3's `path` integrator.

Run by mitsuba_compare.py as `python tools/cycles_render.py JOB.json` (its own process: bpy and
Mitsuba are kept apart). Setup: tools/requirements-peers.txt (bpy 5.0.1 is the newest wheel for
this machine's Python 3.11; it bundles Cycles 5.0 with Embree).

Scene translation (binding conventions of shared/CONVENTIONS.md):
- axes: our world is +Y up, Blender's +Z up; a point (x, y, z) becomes (x, −z, y) (a rotation
  of +90° about X, so handedness is kept). Meshes are written in Blender world coordinates with
  identity object transforms and our per-vertex normals as custom normals.
- environment: Cycles' equirectangular lookup of a Blender direction b (its
  direction_to_equirectangular) is u_c = 1/2 − atan2(b_y, b_x)/(2π), v_c = 1 − acos(b_z)/π,
  with v_c = 1 the image's top row. For our direction d = (x, y, z), b = (x, −z, y), which gives u_c = u + 1/4 and
  1 − v_c = v with u, v our lat-long coordinates. So Cycles gets our map with its columns
  rolled right by W/4 (exact for W divisible by 4) and `Closest` interpolation, which makes it
  the same piecewise-constant function as prt's (Mitsuba's envmap is bilinear instead).
  `cycles_env_columns_shift` and the unit test in tools/test_peer_compare.py check the formula;
  the `probe` suite scene (a mirror sphere) checks it in the rendered images.
- camera: perspective, sensor fit vertical, vertical field of view = prt's fov_y.
- materials: lambert → Diffuse BSDF (roughness 0); mirror → Diffuse(albedo) + Glossy(specular,
  roughness 0, i.e. Cycles' singular reflection with constant reflectance). Cycles shades both
  faces, as prt does.
- bounces: Cycles' max/diffuse/glossy/transmission bounces = prt's `bounces` (0 = direct light
  only, as for prt and Mitsuba max_depth = bounces + 2).

Known difference: on smooth (vertex-normal) meshes Cycles is brighter than prt and Mitsuba on a
one-pixel outline at silhouettes, where the interpolated normal turns away from the viewer
(teapot, 256 spp: mse_ratio 1.35 and mean +0.24 % against prt; with face normals in both 1.01
and +0.04 %). It is Cycles' shading convention there, not a set-up error; it shows in the bias
columns, not in the two-seed error.

Settings that would bias the image or differ from prt are switched off; the list of defaults
changed is read back from Blender itself and returned in the result (`changed_defaults`).
"""

import json
import math
import sys
import time

import os

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from mitsuba_compare import read_obj_full  # noqa: E402  (numpy only; Mitsuba is imported lazily)

# Our (x, y, z), +Y up → Blender (x, −z, y), +Z up.
TO_BLENDER = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def cycles_env_columns_shift(width):
    """Columns to roll our lat-long map (np.roll along axis 1) so that Cycles' equirectangular
    lookup of the converted direction reads the texel prt reads: u_c = u + 1/4."""
    if width % 4:
        raise ValueError(f"environment width {width} is not divisible by 4: the quarter-turn is not a "
                         "whole number of texels")
    return width // 4


def cycles_equirect_uv(b):
    """Cycles' direction_to_equirectangular for Blender-space unit directions b (…, 3): (u, v),
    v = 1 at the +Z pole (the image's top row)."""
    u = 0.5 - np.arctan2(b[..., 1], b[..., 0]) / (2 * math.pi)
    v = 1.0 - np.arccos(np.clip(b[..., 2], -1.0, 1.0)) / math.pi
    return u, v


def look_at_matrix(eye, target, up):
    """4×4 world matrix of a Blender camera (looks down its local −Z, local +Y up)."""
    eye, target, up = (np.asarray(a, dtype=np.float64) for a in (eye, target, up))
    f = target - eye
    f /= np.linalg.norm(f)
    r = np.cross(f, up)
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = r, u, -f, eye
    return m


def snapshot(bpy_struct, names):
    return {n: getattr(bpy_struct, n) for n in names}


def build_scene(bpy, job):
    """Builds the job's scene in an empty Blender file; returns the list of changed defaults."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    c = scene.cycles
    b = int(job["bounces"])
    wanted_cycles = {
        "device": "CPU",
        "samples": int(job["spp"]),
        "use_adaptive_sampling": False,   # fixed sample count, no early stop per pixel
        "use_denoising": False,
        "sampling_pattern": "TABULATED_SOBOL",
        "scrambling_distance": 1.0, "auto_scrambling_distance": False,  # full scrambling (unbiased)
        "sample_clamp_direct": 0.0, "sample_clamp_indirect": 0.0,        # 0 = no clamping
        "blur_glossy": 0.0,               # "filter glossy" off
        "caustics_reflective": True, "caustics_refractive": True,
        "use_light_tree": False, "light_sampling_threshold": 0.0,       # no light culling
        "use_guiding": False,
        "max_bounces": b, "diffuse_bounces": b, "glossy_bounces": b, "transmission_bounces": b,
        "volume_bounces": 0, "min_light_bounces": 0,
        "pixel_filter_type": "BOX",
        # Cycles' box of width w samples the pixel offset uniformly in [−w/2, w/2]² around the
        # pixel centre (filter importance sampling, weight 1): w = 1 is exactly the pixel's
        # square, the box of prt and of Mitsuba's `box` rfilter. The smallest width Cycles
        # allows (0.01) would point-sample pixel centres: a different (aliased) image.
        "filter_width": 1.0,
        "film_exposure": 1.0,
        "use_auto_tile": False,
        "seed": int(job["seeds"][0]),
    }
    changed = []
    before = snapshot(c, wanted_cycles)
    for k, v in wanted_cycles.items():
        setattr(c, k, v)
    for k, v in wanted_cycles.items():
        if k not in ("samples", "seed") and not k.endswith("bounces") and before[k] != v:
            changed.append(f"scene.cycles.{k}: {before[k]!r} → {v!r}")
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = job["width"], job["height"], 100
    r.pixel_aspect_x = r.pixel_aspect_y = 1.0
    r.use_persistent_data = True  # a render after the first re-uses the BVH: render-only timing
    r.use_compositing = False
    r.use_sequencer = False
    r.film_transparent = False
    r.use_motion_blur = False
    r.image_settings.file_format = "OPEN_EXR"
    r.image_settings.color_depth = "32"
    r.image_settings.exr_codec = "ZIP"
    r.image_settings.color_mode = "RGB"
    scene.view_settings.view_transform = "Standard"  # EXR output is linear in any case

    build_world(bpy, scene, job)
    cam = job["camera"]
    cd = bpy.data.cameras.new("camera")
    cd.sensor_fit = "VERTICAL"
    cd.angle_y = math.radians(cam["fov"])
    cd.clip_start, cd.clip_end = cam["near"], cam["far"]
    co = bpy.data.objects.new("camera", cd)
    eye = TO_BLENDER @ np.array(cam["eye"])
    target = TO_BLENDER @ np.array(cam["target"])
    up = TO_BLENDER @ np.array(cam["up"])
    from mathutils import Matrix  # row-major (a plain nested list would be read as columns)
    co.matrix_world = Matrix([list(row) for row in look_at_matrix(eye, target, up)])
    scene.collection.objects.link(co)
    scene.camera = co

    materials = {name: build_material(bpy, name, m, changed) for name, m in job["materials"].items()}
    for k, sh in enumerate(job["shapes"]):
        build_mesh(bpy, scene, f"shape{k}", sh, materials[sh["material"]], changed if k == 0 else None)
    return changed


def build_world(bpy, scene, job):
    world = bpy.data.worlds.new("env")
    scene.world = world
    world.use_nodes = True
    nt = world.node_tree
    nt.nodes.clear()
    tex = nt.nodes.new("ShaderNodeTexEnvironment")
    tex.image = bpy.data.images.load(job["env"])
    tex.interpolation = "Closest"   # piecewise constant over texels, as prt's map
    tex.projection = "EQUIRECTANGULAR"
    bg = nt.nodes.new("ShaderNodeBackground")
    bg.inputs["Strength"].default_value = 1.0
    out = nt.nodes.new("ShaderNodeOutputWorld")
    nt.links.new(tex.outputs["Color"], bg.inputs["Color"])
    nt.links.new(bg.outputs["Background"], out.inputs["Surface"])


def build_material(bpy, name, m, changed):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    if mat.cycles.use_bump_map_correction:
        changed.append(f"material[{name}].cycles.use_bump_map_correction: True → False")
        mat.cycles.use_bump_map_correction = False
    nt = mat.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    diffuse = nt.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = list(m["albedo"]) + [1.0]
    diffuse.inputs["Roughness"].default_value = 0.0  # Lambert
    shader = diffuse.outputs["BSDF"]
    if m["type"] == "mirror":
        glossy = nt.nodes.new("ShaderNodeBsdfGlossy")
        glossy.inputs["Color"].default_value = list(m["specular"]) + [1.0]
        glossy.inputs["Roughness"].default_value = 0.0  # singular: a perfect mirror
        add = nt.nodes.new("ShaderNodeAddShader")
        nt.links.new(diffuse.outputs["BSDF"], add.inputs[0])
        nt.links.new(glossy.outputs["BSDF"], add.inputs[1])
        shader = add.outputs["Shader"]
    elif m["type"] != "lambert":
        raise ValueError(f"material {name}: type {m['type']} has no Cycles translation here")
    nt.links.new(shader, out.inputs["Surface"])
    return mat


def build_mesh(bpy, scene, name, sh, mat, changed):
    """A mesh in Blender world coordinates (object transform applied here, in f64), with the
    file's per-vertex normals as custom normals and Cycles' shadow-terminator offsets off."""
    v, n, f = read_obj_full(sh["filename"])
    if n is None:
        raise ValueError(f"{sh['filename']}: every face corner needs a `vn` normal")
    m = np.array(sh["to_world"], dtype=np.float64)
    lin = m[:3, :3]
    vw = (v @ lin.T + m[:3, 3]) @ TO_BLENDER.T
    nw = n @ np.linalg.inv(lin) @ TO_BLENDER.T  # (M⁻ᵀ n) as rows
    nw /= np.linalg.norm(nw, axis=1, keepdims=True)
    me = bpy.data.meshes.new(name)
    me.from_pydata(vw, [], f)
    me.update()
    me.polygons.foreach_set("use_smooth", np.ones(len(f), dtype=bool))
    me.normals_split_custom_set_from_vertices(nw)
    me.materials.append(mat)
    ob = bpy.data.objects.new(name, me)
    offsets = {"shadow_terminator_geometry_offset": 0.0, "shadow_terminator_shading_offset": 0.0,
               "shadow_terminator_normal_offset": 0.0}
    for k, val in offsets.items():
        if hasattr(ob, k):
            if changed is not None and getattr(ob, k) != val:
                changed.append(f"object.{k}: {getattr(ob, k):g} → {val:g}")
            setattr(ob, k, val)
    for k in ("shadow_terminator_geometry_offset", "shadow_terminator_offset"):  # legacy names
        if hasattr(ob.cycles, k):
            setattr(ob.cycles, k, 0.0)
    scene.collection.objects.link(ob)


def render_to_array(bpy, path):
    t = time.perf_counter()
    bpy.context.scene.render.filepath = path
    bpy.ops.render.render(write_still=True)
    secs = time.perf_counter() - t
    meta = cycles_times(path)
    img = bpy.data.images.load(path)
    w, h = img.size
    px = np.empty(w * h * 4, dtype=np.float32)
    img.pixels.foreach_get(px)
    bpy.data.images.remove(img)
    return px.reshape(h, w, 4)[::-1, :, :3].copy(), secs, meta  # Blender rows are bottom-up


def cycles_times(exr_path):
    """Cycles' own `render_time` and `synchronization_time` from the EXR's header (strings
    "MM:SS.ss"), in seconds; {} if they cannot be read."""
    import re
    try:
        with open(exr_path, "rb") as f:
            head = f.read(65536)
    except OSError:
        return {}
    out = {}
    for key in ("render_time", "synchronization_time"):
        m = re.search(rb"cycles\.ViewLayer\." + key.encode() + rb"\x00string\x00.{4}(\d+):(\d+\.\d+)", head, re.S)
        if m:
            out[key] = 60 * int(m.group(1)) + float(m.group(2))
    return out


def main(job_path):
    with open(job_path) as f:
        job = json.load(f)
    import bpy

    t = time.perf_counter()
    changed = build_scene(bpy, job)
    out = {"blender": bpy.app.version_string, "build_seconds": time.perf_counter() - t,
           "changed_defaults": changed}
    scene = bpy.context.scene
    # Warm-up: one render at 1 spp builds the BVH and loads kernels (kept: persistent data).
    scene.cycles.samples, scene.cycles.seed = 1, int(job["warmup_seed"])
    _, out["warmup_seconds"], out["warmup_cycles_times"] = render_to_array(bpy, job["outs"][0] + ".warmup.exr")
    scene.cycles.samples = int(job["spp"])
    out["seconds"], out["cycles_times"] = [], []
    for seed, path in zip(job["seeds"], job["outs"]):
        scene.cycles.seed = int(seed)
        img, secs, meta = render_to_array(bpy, path + ".exr")
        np.save(path, img)
        out["seconds"].append(secs)
        out["cycles_times"].append(meta)
    out["samples"] = scene.cycles.samples
    with open(job["result"], "w") as f:
        json.dump(out, f)


if __name__ == "__main__":
    main(sys.argv[1])
