#!/usr/bin/env python3
"""Self-test of the pure functions of tools/mitsuba_compare.py --suite and tools/cycles_render.py
(numpy only: neither Mitsuba nor bpy is imported). Not part of CI (the tool is not run there).

Run: python3 tools/test_peer_compare.py   (or tools/.venv/bin/python tools/test_peer_compare.py)
"""

import contextlib
import io
import math
import struct
import tempfile
import os
import sys
import unittest

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import cycles_render as cr  # noqa: E402
import mitsuba_compare as mc  # noqa: E402
import hit_miss_probe as hm  # noqa: E402
import ray_peer_probe as rp  # noqa: E402


def synthetic(seed, shape=(100, 100, 3)):
    """A positive 'true image' t and a per-pixel noise level σ (known variance σ² per render)."""
    rng = np.random.default_rng(seed)
    t = 0.2 + rng.random(shape)
    sigma = 0.02 + 0.08 * rng.random(shape)
    return rng, t, sigma


def tolerance_of_error(sigma, k=5.0):
    """k standard deviations of the two-seed estimate, relative. For Gaussian noise each
    (x1 − x2)²/2 is σ² χ²₁ (mean σ², variance 2σ⁴), so the relative standard deviation of
    mean((x1 − x2)²/2) is sqrt(2 Σσ⁴)/Σσ², and that of its square root half of it."""
    s2 = sigma.ravel() ** 2
    return k * 0.5 * math.sqrt(2.0 * np.sum(s2 * s2)) / np.sum(s2)


class TwoSeedError(unittest.TestCase):
    def test_matches_known_variance(self):
        rng, t, sigma = synthetic(1)
        x1 = t + sigma * rng.standard_normal(t.shape)
        x2 = t + sigma * rng.standard_normal(t.shape)
        mask = np.ones(t.shape, dtype=bool)
        want = math.sqrt(np.mean(sigma ** 2) / np.mean(t ** 2))
        got = mc.two_seed_error(x1, x2, t, mask)
        self.assertLess(abs(got / want - 1.0), tolerance_of_error(sigma), (got, want))

    def test_below_the_reference_noise(self):
        """A reference 3× noisier than the method: the distance to the reference measures the
        reference (≈ sqrt(1 + 9) = 3.2× the true error), the two-seed estimate does not. The
        reference's noise only enters through its norm, so the expected value uses that norm."""
        rng, t, sigma = synthetic(2)
        ref = t + 3.0 * sigma * rng.standard_normal(t.shape)
        x1 = t + sigma * rng.standard_normal(t.shape)
        x2 = t + sigma * rng.standard_normal(t.shape)
        mask = np.ones(t.shape, dtype=bool)
        want = math.sqrt(np.mean(sigma ** 2) / np.mean(ref ** 2))
        got = mc.two_seed_error(x1, x2, ref, mask)
        self.assertLess(abs(got / want - 1.0), tolerance_of_error(sigma))
        naive = mc.rel_l2(x1, ref, mask)
        self.assertGreater(naive / want, 2.5)  # sqrt(10) = 3.16 expected; 2.5 is far outside noise

    def test_mask_and_bias(self):
        """Only masked pixels count; a bias common to both seeds does not change the estimate
        (the bias check is bias_stats' job, and it sees this one)."""
        rng, t, sigma = synthetic(3)
        mask = np.zeros(t.shape, dtype=bool)
        mask[:50] = True
        n1, n2 = (sigma * rng.standard_normal(t.shape) for _ in range(2))
        x1, x2 = t + n1, t + n2
        x1[~mask] = 1e6  # outside the mask: must not matter
        a = mc.two_seed_error(x1, x2, t, mask)
        b = mc.two_seed_error(x1 + 0.05, x2 + 0.05, t, mask)
        self.assertAlmostEqual(a, b, places=12)
        var_mean = (x1 - x2) ** 2 / 4.0
        zero = np.zeros_like(t)
        unbiased = mc.bias_stats(0.5 * (x1 + x2), var_mean, t, zero, mask)
        biased = mc.bias_stats(0.5 * (x1 + x2) + 0.05, var_mean, t, zero, mask)
        # mse_ratio of an unbiased image: 1 within a few times sqrt(2/N) (N = 15000 here);
        # z of its mean difference is standard normal.
        self.assertLess(abs(unbiased["mse_ratio"] - 1.0), 0.1)
        self.assertLess(abs(unbiased["mean_difference_z"]), 5.0)
        self.assertGreater(biased["mean_difference_z"], 50.0)


class Costs(unittest.TestCase):
    def test_cost_and_ratios(self):
        self.assertAlmostEqual(mc.cost_at_equal_error(4.0, 0.01), 4e-4)
        costs = {"prt": 2.0, "a": 4.0, "b": 1.0, "c": 8.0}
        ratios, best, r = mc.cost_ratios(costs)
        self.assertEqual(ratios, {"a": 0.5, "b": 2.0, "c": 0.25})
        self.assertEqual((best, r), ("b", 2.0))

    def test_equal_error_meaning(self):
        """err² ∝ 1/time for a Monte Carlo method: halving the error takes 4× the time, and the
        cost does not change."""
        self.assertAlmostEqual(mc.cost_at_equal_error(1.0, 0.02), mc.cost_at_equal_error(4.0, 0.01))

    def test_parse_peers(self):
        self.assertEqual(mc.parse_peers("llvm_multijitter,cycles"), ["llvm_multijitter", "cycles"])
        for bad in ("llvm_stratified", "cuda_independent", "blender"):
            with self.assertRaises(ValueError):
                mc.parse_peers(bad)

    def test_parse_prt_seconds(self):
        err = ("warning: x\nrendered 64×48 at 64 spp, bounces 1, seed 0 in 0.27 s (1117916 samples/s), "
               "noise 3.4 % → out.exr\n")
        self.assertEqual(mc.parse_prt_render_seconds(err), 0.27)
        with self.assertRaises(ValueError):
            mc.parse_prt_render_seconds("nothing here")


class PairedTiming(unittest.TestCase):
    def test_ratios_and_median(self):
        """Each round's ratio is prt's time per sample over Mitsuba's (Mitsuba's sample count
        may differ from prt's spp), and the figure is their median."""
        rounds = [[6.0, 4.0], [5.0, 5.0], [9.0, 3.0]]
        ratios, median = mc.paired_ratios(rounds, 1024, 512)
        self.assertEqual([round(x, 12) for x in ratios], [0.75, 0.5, 1.5])
        self.assertEqual(median, 0.75)
        self.assertEqual(mc.paired_ratios([], 1024, 1024), ([], None))

    def test_common_drift_cancels(self):
        """A machine that slows both renderers of a round by the same factor leaves every
        round's ratio, and so the median, unchanged."""
        slow = [1.0, 1.3, 0.8, 1.6]
        rounds = [[6.0 * f, 4.0 * f] for f in slow]
        ratios, median = mc.paired_ratios(rounds, 1024, 1024)
        for r in ratios:
            self.assertAlmostEqual(r, 1.5)
        self.assertAlmostEqual(median, 1.5)

    def test_prt_command(self):
        class Args:
            prt, spp, prt_sampler, prt_env_sampling, prt_split_lobes = "prt", 64, "single", "per-normal", "mirror"
        cmd = mc.prt_render_cmd(Args, "s.toml", {"bounces": 2}, 1, "o.exr")
        self.assertEqual(cmd[:3], ["prt", "render", "s.toml"])
        for flag, value in (("--spp", "64"), ("--bounces", "2"), ("--seed", "1"), ("--sampler", "single"),
                            ("--env-sampling", "per-normal"), ("--split-lobes", "mirror"), ("--out", "o.exr")):
            self.assertEqual(cmd[cmd.index(flag) + 1], value)


class Host(unittest.TestCase):
    def test_widest_simd_from_cpuinfo(self):
        text = ("processor\t: 0\nmodel name\t: AMD EPYC 7B13\nflags\t\t: fpu sse2 avx fma avx2\n\n"
                "processor\t: 1\nmodel name\t: other\nflags\t\t: avx512f\n")
        self.assertEqual(mc.host_simd(text), {"model": "AMD EPYC 7B13", "simd": "AVX2", "fma": True})
        wide = mc.host_simd("model name : X\nflags : sse2 avx avx2 avx512f avx512bw\n")
        self.assertEqual(wide["simd"], "AVX-512")
        self.assertFalse(wide["fma"])
        self.assertEqual(mc.host_simd(""), {"model": None, "simd": None, "fma": False})
        line = mc.host_line({"model": "M", "cores": 2, "simd": "AVX2"})
        self.assertIn("M, 2 cores, widest SIMD AVX2", line)
        self.assertEqual(mc.host_line(None), "")


class CyclesEnvironment(unittest.TestCase):
    def test_rolled_map_reads_the_same_texel(self):
        """For directions all over the sphere, Cycles' equirectangular lookup of the Blender
        direction in the rolled map returns the texel that CONVENTIONS.md's lat-long lookup of
        our direction returns in the original map."""
        rng = np.random.default_rng(4)
        h, w = 32, 64
        env = rng.random((h, w))
        rolled = np.roll(env, cr.cycles_env_columns_shift(w), axis=1)
        d = rng.standard_normal((20000, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        u = np.mod(np.arctan2(d[:, 0], -d[:, 2]) / (2 * math.pi), 1.0)
        v = np.arccos(d[:, 1]) / math.pi
        ours = env[np.minimum((v * h).astype(int), h - 1), np.minimum((u * w).astype(int), w - 1)]
        uc, vc = cr.cycles_equirect_uv(d @ cr.TO_BLENDER.T)
        col = np.mod(np.floor(uc * w).astype(int), w)
        row_from_bottom = np.minimum(np.floor(vc * h).astype(int), h - 1)
        theirs = rolled[h - 1 - row_from_bottom, col]  # Blender's v = 0 is the file's last row
        # Directions within float rounding of a texel edge may land on either side: allow 0.1 %.
        self.assertLess(np.mean(ours != theirs), 1e-3)

    def test_axes(self):
        """+Y up becomes +Z up, −Z (our u = 0 direction) becomes +Y; the map is right-handed."""
        m = cr.TO_BLENDER
        np.testing.assert_array_equal(m @ [0, 1, 0], [0, 0, 1])
        np.testing.assert_array_equal(m @ [0, 0, -1], [0, 1, 0])
        self.assertAlmostEqual(np.linalg.det(m), 1.0)
        with self.assertRaises(ValueError):
            cr.cycles_env_columns_shift(62)

    def test_camera_matrix(self):
        m = cr.look_at_matrix([0, -3, 1], [0, 0, 1], [0, 0, 1])
        np.testing.assert_allclose(m[:3, 3], [0, -3, 1])
        np.testing.assert_allclose(m[:3, 2], [0, -1, 0], atol=1e-12)  # local +Z points backwards
        np.testing.assert_allclose(m[:3, 1], [0, 0, 1], atol=1e-12)   # local +Y is up
        np.testing.assert_allclose(m[:3, :3].T @ m[:3, :3], np.eye(3), atol=1e-12)


class HitMissProbe(unittest.TestCase):
    def test_variants(self):
        base = {"camera": {"eye": [0.0, 0.0, 3.6], "target": [0.0, 0.0, 0.0], "fov": 40.0},
                "objects": [{"mesh": "sphere.obj", "translate": [0.0, 0.0, 0.0]}]}
        before = repr(base)
        self.assertEqual(hm.variant_spec(base, "suite"), base)
        hit = hm.variant_spec(base, "hit")
        self.assertEqual(hit["camera"]["eye"], [0.0, 0.0, 1.9])
        # Every camera ray of the 4:3 image meets the unit sphere from 1.9 away: the corner
        # ray's angle to the axis is below the sphere's angular radius asin(1 / 1.9).
        tan_y = math.tan(math.radians(base["camera"]["fov"] / 2))
        corner = math.atan(math.hypot(tan_y, tan_y * 4.0 / 3.0))
        self.assertLess(corner, math.asin(1.0 / 1.9))
        miss = hm.variant_spec(base, "miss")
        self.assertEqual(miss["objects"][0]["translate"], [0.0, 100.0, 0.0])
        self.assertEqual(repr(base), before)  # the base spec is not changed

    def test_table_ratios(self):
        """Per variant, min and median in ns per sample and prt's ratio to each peer."""
        class Args:
            width, height, spp, rounds = 10, 10, 10, 3  # 1000 samples: 1 µs = 1 ns/sample
            threads = 1
        times = {}
        for name in hm.VARIANTS:
            times[(name, "prt")] = [3e-6, 2e-6, 9e-6]  # min 2, median 3
            times[(name, "mitsuba")] = [1e-6, 1.5e-6, 1e-6]  # min 1, median 1
            times[(name, "scalar")] = [4e-6, 6e-6, 5e-6]  # min 4, median 5
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            hm.print_table(times, ["mitsuba", "scalar"], Args())
        rows = [r for r in out.getvalue().splitlines() if r.startswith("| miss")]
        self.assertEqual(rows, ["| miss | 2 / 3 | 1 / 1 | 2.00 / 3.00 | 4 / 5 | 0.50 / 0.60 |"])

class RayPeerProbe(unittest.TestCase):
    def test_camera_rays(self):
        """Unit directions; the grid's centre looks at the target, row 0 is the top row, and
        the corner pixel centre is (1 − 1/size) of the half field of view off the axis."""
        eye, target, size = np.array([0.0, 1.0, 5.0]), np.array([0.0, 1.0, 0.0]), 4
        o, d = rp.camera_rays(eye, target, size, 40.0)
        self.assertEqual(o.shape, (16, 3))
        np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, rtol=1e-12)
        np.testing.assert_array_equal(o, np.tile(eye, (16, 1)))
        mean = d.mean(axis=0)
        np.testing.assert_allclose(mean / np.linalg.norm(mean), [0.0, 0.0, -1.0], atol=1e-12)
        self.assertGreater(d[0, 1], 0.0)  # top row looks up
        self.assertLess(d[0, 0], 0.0)  # first column looks left (−x seen from +z)
        half = math.tan(math.radians(20.0)) * (1.0 - 1.0 / size)
        np.testing.assert_allclose(d[0] / -d[0, 2], [-half, half, -1.0], rtol=1e-12)

    def test_random_rays(self):
        """Origins at twice the radius, each ray passing within half the radius of the centre."""
        center, radius = np.array([1.0, -2.0, 0.5]), 3.0
        o, d = rp.random_rays(1000, center, radius, seed=3)
        np.testing.assert_allclose(np.linalg.norm(o - center, axis=1), 2.0 * radius, rtol=1e-12)
        np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, rtol=1e-12)
        to_c = center - o
        miss = np.linalg.norm(to_c - (to_c * d).sum(axis=1, keepdims=True) * d, axis=1)
        self.assertTrue(np.all(miss <= 0.5 * radius + 1e-9))

    def test_surface_rays(self):
        """On a unit right triangle in z = 0 (normal +z): origins 1e-4·r above it and inside it,
        directions in the upper hemisphere with E[cos θ] = 2/3 (cosine-distributed)."""
        positions = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
        faces = np.array([[0, 1, 2]])
        n = 20000
        o, d = rp.surface_rays(n, positions, faces, radius=2.0, seed=5)
        np.testing.assert_allclose(o[:, 2], 2e-4, rtol=1e-9)
        self.assertTrue(np.all((o[:, 0] >= 0) & (o[:, 1] >= 0) & (o[:, 0] + o[:, 1] <= 1.0)))
        np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, rtol=1e-12)
        self.assertTrue(np.all(d[:, 2] > 0.0))
        # cos θ of a cosine-distributed direction has mean 2/3 and variance 1/18.
        self.assertLess(abs(d[:, 2].mean() - 2.0 / 3.0), 5.0 * math.sqrt(1.0 / 18.0 / n))
        # Area-uniform points: E[x] = 1/3 on this triangle, variance 1/18.
        self.assertLess(abs(o[:, 0].mean() - 1.0 / 3.0), 5.0 * math.sqrt(1.0 / 18.0 / n))

    def test_obj_faces(self):
        """The OBJ reader the probe uses (`mitsuba_compare.read_obj`): `v//vn` and `v/vt/vn`
        references keep their vertex index, 0-based, and a quad becomes a fan of two."""
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "m.obj")
            with open(path, "w") as f:
                f.write("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1//1 2//2 3//3\n"
                        "f 2/1/2 4/1/4 3/1/3\nf 1 2 4 3\n")
            verts, faces = mc.read_obj(path)
        self.assertEqual(verts.shape, (4, 3))
        np.testing.assert_array_equal(faces, [[0, 1, 2], [1, 3, 2], [0, 1, 3], [0, 3, 2]])

    def test_ray_file(self):
        """Six little-endian f32 per ray, origin then direction, −0 written as +0."""
        o = np.array([[1.0, 2.0, 3.0]])
        d = np.array([[-0.0, 0.6, -0.8]])
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "r.f32")
            rp.write_rays(path, o, d)
            raw = open(path, "rb").read()
        self.assertEqual(raw, struct.pack("<6f", 1.0, 2.0, 3.0, 0.0, 0.6, -0.8))

    def test_agreement_threshold(self):
        """At most one ray in a thousand may disagree."""
        a = np.zeros(2000, dtype=bool)
        b = a.copy()
        b[:2] = True
        self.assertEqual(rp.check_agreement("x", a, b), 2)
        b[2] = True
        with self.assertRaises(SystemExit):
            rp.check_agreement("x", a, b)


if __name__ == "__main__":
    unittest.main()
