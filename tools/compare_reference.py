#!/usr/bin/env python3
"""Independent reference data for the tests of the prt-compare crate (crates/compare).

Writes into crates/compare/tests/data/:
  ref.exr          32x24 linear RGB f32 reference (R, G, B channels), HDR values up to ~6
  test.exr         32x24 linear RGB f32 test image with an alpha channel (A = 1, to be ignored);
                   some values are negative (as SH ringing produces) and some exceed 1
  ref.png, test.png  the 8-bit sRGB PNG views of both (exposure 0 EV, clamp, sRGB OETF, round)
  mask.png         32x24 8-bit gray mask: 255 inside an ellipse, 0 outside
  expected.json    the metrics, computed with scikit-image and NumPy (see "description")

The metrics use scikit-image's peak_signal_noise_ratio, mean_squared_error and
normalized_root_mse (normalization="euclidean", which is sqrt(sum((a-b)^2)/sum(b^2)) with b the
reference); nothing is shared with the Rust code. Deterministic (fixed seed).

Usage: tools/.venv/bin/python tools/compare_reference.py
"""

import json
import os
import sys

import imageio
import imageio.v3 as iio
import matplotlib
import numpy as np
import OpenEXR
import skimage
from matplotlib import colormaps
from skimage.metrics import mean_squared_error, normalized_root_mse, peak_signal_noise_ratio

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "crates", "compare", "tests", "data")
W, H = 32, 24
SEED = 20250101


def oetf(x):
    """sRGB OETF (IEC 61966-2-1), linear [0,1] -> encoded."""
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)


def eotf(v):
    """sRGB EOTF, encoded [0,1] -> linear."""
    return np.where(v <= 0.04045, v / 12.92, np.power((v + 0.055) / 1.055, 2.4))


def png_view(linear, exposure_ev=0.0):
    """The 8-bit view of CONVENTIONS: exposure, clamp [0,1], sRGB curve, round half up."""
    x = np.clip(linear.astype(np.float64) * 2.0**exposure_ev, 0.0, 1.0)
    return np.floor(oetf(x) * 255.0 + 0.5).astype(np.uint8)


def write_exr(path, rgb, alpha=None):
    channels = {"RGB": rgb.astype(np.float32)}
    if alpha is not None:
        channels = {"RGBA": np.dstack([rgb, alpha]).astype(np.float32)}
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, channels) as f:
        f.write(path)


def read_exr(path):
    with OpenEXR.File(path) as f:
        ch = f.channels()
        key = "RGBA" if "RGBA" in ch else "RGB"
        return np.asarray(ch[key].pixels, dtype=np.float32)[:, :, :3]


def stats(test, ref, test8, ref8):
    """Metrics on arrays of shape (..., 3): linear f64 and their 8-bit views."""
    t = test.astype(np.float64)
    r = ref.astype(np.float64)
    return {
        "pixels": int(r.size // 3),
        "psnr_ldr": float(peak_signal_noise_ratio(ref8.astype(np.float64), test8.astype(np.float64), data_range=255)),
        "psnr_hdr": float(peak_signal_noise_ratio(r, t, data_range=float(r.max()))),
        "rmse": float(np.sqrt(mean_squared_error(r, t))),
        "rel_l2": float(normalized_root_mse(r, t, normalization="euclidean")),
        "mae": float(np.mean(np.abs(t - r))),
        "max_abs": float(np.max(np.abs(t - r))),
        "hdr_peak": float(r.max()),
    }


def main():
    os.makedirs(OUT, exist_ok=True)
    rng = np.random.default_rng(SEED)
    yy, xx = np.mgrid[0:H, 0:W]
    u = (xx + 0.5) / W
    v = (yy + 0.5) / H
    ref = np.dstack([0.05 + 1.6 * u * v, 0.1 + 0.9 * (1 - u) * v, 0.02 + 0.5 * u]).astype(np.float64)
    ref *= np.exp(rng.normal(0.0, 0.2, size=ref.shape))
    hot = rng.choice(W * H, size=6, replace=False)
    ref.reshape(-1, 3)[hot] *= rng.uniform(3.0, 6.0, size=(6, 1))
    test = ref * (1.0 + rng.normal(0.0, 0.08, size=ref.shape)) + rng.normal(0.0, 0.01, size=ref.shape)
    dark = rng.choice(W * H, size=10, replace=False)
    test.reshape(-1, 3)[dark] = rng.uniform(-0.05, -0.001, size=(10, 3))
    ref = ref.astype(np.float32)
    test = test.astype(np.float32)

    write_exr(os.path.join(OUT, "ref.exr"), ref)
    write_exr(os.path.join(OUT, "test.exr"), test, alpha=np.ones((H, W), np.float32))
    # Read back: the expected values are for exactly what the files hold.
    ref_f = read_exr(os.path.join(OUT, "ref.exr"))
    test_f = read_exr(os.path.join(OUT, "test.exr"))
    assert np.array_equal(ref_f, ref) and np.array_equal(test_f, test), "EXR round trip"

    ref8 = png_view(ref)
    test8 = png_view(test)
    iio.imwrite(os.path.join(OUT, "ref.png"), ref8)
    iio.imwrite(os.path.join(OUT, "test.png"), test8)
    assert np.array_equal(iio.imread(os.path.join(OUT, "ref.png")), ref8), "PNG round trip"

    mask = ((u - 0.5) / 0.4) ** 2 + ((v - 0.5) / 0.35) ** 2 <= 1.0
    iio.imwrite(os.path.join(OUT, "mask.png"), (mask * 255).astype(np.uint8))
    assert 0 < mask.sum() < W * H

    # PNG images decoded to linear by the exact EOTF, compared as images in their own right.
    # Rounded to f32, the precision of the Rust Image.
    ref_png_lin = eotf(ref8 / 255.0).astype(np.float32)
    test_png_lin = eotf(test8 / 255.0).astype(np.float32)
    # Their 8-bit views give back the PNG bytes exactly (checked here independently).
    assert np.array_equal(png_view(ref_png_lin), ref8) and np.array_equal(png_view(test_png_lin), test8)

    ev = 1.5
    out = {
        "description": (
            "Metrics of test.exr against ref.exr (reference) computed with scikit-image "
            "(peak_signal_noise_ratio: data_range=255 on the 8-bit sRGB views, data_range=ref max "
            "on linear f64; mean_squared_error; normalized_root_mse euclidean = rel_l2) and NumPy "
            "(mae, max_abs). 'whole': all pixels; 'masked': pixels where mask.png is nonzero; "
            "'exposure_1_5': whole image with the LDR view at +1.5 EV; 'png': the PNG views "
            "decoded by the sRGB EOTF compared as linear images. Views: clamp(x*2^EV,0,1), "
            "sRGB OETF, floor(255 v + 0.5)."
        ),
        "generator": "tools/compare_reference.py",
        "versions": {
            "python": sys.version.split()[0],
            "numpy": np.__version__,
            "scikit-image": skimage.__version__,
            "imageio": imageio.__version__,
            "matplotlib": matplotlib.__version__,
            "OpenEXR": OpenEXR.__version__,
        },
        "seed": SEED,
        "width": W,
        "height": H,
        "masked_pixels": int(mask.sum()),
        "whole": stats(test, ref, test8, ref8),
        "masked": stats(test[mask], ref[mask], test8[mask], ref8[mask]),
        "exposure_1_5": stats(test, ref, png_view(test, ev), png_view(ref, ev)),
        "png": stats(test_png_lin, ref_png_lin, test8, ref8),
        "viridis_table": [[float(c) for c in rgb] for rgb in np.asarray(colormaps["viridis"].colors)],
    }
    path = os.path.join(OUT, "expected.json")
    with open(path, "w") as f:
        json.dump(out, f, indent=1)
        f.write("\n")
    for name in ["ref.exr", "test.exr", "ref.png", "test.png", "mask.png", "expected.json"]:
        print("wrote", os.path.join(OUT, name), os.path.getsize(os.path.join(OUT, name)), "bytes")
    print(json.dumps({k: out[k] for k in ["whole", "masked"]}, indent=1))


if __name__ == "__main__":
    main()
