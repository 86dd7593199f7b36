#!/usr/bin/env python3
"""Opens a `prt view` page in headless Chromium (WebGL2 through SwiftShader) and checks it.

    python3 tools/engine_check.py PAGE.html --rotations 0,120,240 --out-dir DIR
        [--reference-pattern DIR/ref_{deg}.png --min-psnr 40] [--screenshot shot.png]

Checks, each printed, and exit status 1 when one fails:
- the page loads from file:// (no network) with WebGL2 and no browser-console error (SEVERE)
  and its script ran (`window.prtView`);
- for each rotation (degrees about +Y, as `prt relight --rotate-y`), the canvas is drawn
  (`prtView.setRotation`) and saved as DIR/canvas_{deg}.png (RGBA: alpha 0 where no object
  covers the pixel's centre); turning the map changes the pixels; moving the exposure
  changes them and moving it back restores them;
- with --reference-pattern: the canvas against `prt relight --rotate-y DEG --png` of the
  same bake (8-bit sRGB views, exposure 0), PSNR over the object pixels whose 3×3
  neighbourhood the same object covers (interior pixels, from the page's object-id pass: the
  GPU takes one sample at the pixel centre, prt a box filter over the pixel, which differ
  only where an edge — against the background or another object — crosses it) at least
  --min-psnr dB;
- the frame time (SH rotation on the CPU, shading and drawing, `gl.finish()`), the median of
  the frames drawn, is printed as JSON on the last line with the PSNRs:
  {"frame_ms_median": ..., "frames": N, "psnr": {"0": ..., ...}, "renderer": "..."}.

Needs Debian's chromium and chromium-driver, PyPI's selenium, numpy and Pillow
(tools/requirements-browser.txt).
"""

import argparse
import base64
import io
import json
import math
import os
import sys
import time


def png_rgba(data):
    from PIL import Image
    import numpy as np
    return np.asarray(Image.open(io.BytesIO(data)).convert("RGBA"), dtype=np.float64)


def interior(ids):
    """Pixels an object covers whose eight neighbours the same object covers (ids: 0 for
    the background, else the object's index + 1)."""
    import numpy as np
    out = ids > 0
    h, w = ids.shape
    padded = np.zeros((h + 2, w + 2), dtype=ids.dtype)
    padded[1:-1, 1:-1] = ids
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            out &= padded[1 + dy:h + 1 + dy, 1 + dx:w + 1 + dx] == ids
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("page")
    ap.add_argument("--rotations", default="0,120,240")
    ap.add_argument("--out-dir", required=True)
    ap.add_argument("--reference-pattern")
    ap.add_argument("--min-psnr", type=float, default=40.0)
    ap.add_argument("--screenshot")
    ap.add_argument("--window", default="1400,1100", help="browser window WIDTH,HEIGHT")
    ap.add_argument("--chromium", default=os.environ.get("CHROMIUM", "/usr/bin/chromium"))
    ap.add_argument("--chromedriver", default=os.environ.get("CHROMEDRIVER", "/usr/bin/chromedriver"))
    a = ap.parse_args()

    import numpy as np
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    os.makedirs(a.out_dir, exist_ok=True)
    failures = []

    def check(ok, what):
        print(("ok   " if ok else "FAIL ") + what, flush=True)
        if not ok:
            failures.append(what)

    opts = webdriver.ChromeOptions()
    opts.binary_location = a.chromium
    for flag in ["--headless=new", "--no-sandbox", "--use-angle=swiftshader",
                 "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist", "--disable-quic",
                 "--no-first-run", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", f"--window-size={a.window}"]:
        opts.add_argument(flag)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(a.chromedriver), options=opts)
    result = {"psnr": {}}
    try:
        driver.get("file://" + os.path.abspath(a.page))
        for _ in range(600):
            if driver.execute_script("return !!window.prtView"):
                break
            time.sleep(0.1)
        ready = driver.execute_script("return !!window.prtView")
        notes = driver.find_element("id", "notes").text
        check(ready, "the page's script ran with WebGL2 (window.prtView)" + (f"; notes: {notes}" if notes else ""))
        if not ready:
            raise SystemExit(1)

        def canvas_png():
            url = driver.execute_script("return document.getElementById('canvas').toDataURL('image/png')")
            return base64.b64decode(url.split(",", 1)[1])

        shots = {}
        for deg in [float(d) for d in a.rotations.split(",")]:
            driver.execute_script("return window.prtView.setRotation(arguments[0])", deg)
            data = canvas_png()
            name = f"{deg:g}"
            with open(os.path.join(a.out_dir, f"canvas_{name}.png"), "wb") as f:
                f.write(data)
            shots[name] = png_rgba(data)
        names = list(shots)
        first = shots[names[0]]
        check(first[..., 3].max() > 0, f"the canvas shows the object ({int((first[..., 3] > 0).sum())} covered pixels)")
        if len(names) > 1:
            moved = np.abs(shots[names[1]][..., :3] - first[..., :3]).max()
            check(moved > 0, f"turning the map to {names[1]}° changes the pixels (largest change {moved:.0f} codes)")
        driver.execute_script("window.prtView.setRotation(arguments[0])", float(names[0]))
        base = canvas_png()
        driver.execute_script("window.prtView.setExposure(1.5)")
        brighter = canvas_png()
        driver.execute_script("window.prtView.setExposure(0)")
        back = canvas_png()
        check(png_rgba(brighter)[..., :3].sum() > png_rgba(base)[..., :3].sum(),
              "+1.5 EV brightens the canvas")
        check(np.array_equal(png_rgba(back), png_rgba(base)), "back to 0 EV restores it exactly")

        # Which object covers each pixel's centre (the page's id pass).
        driver.execute_script("window.prtView.drawObjectIds()")
        ids = png_rgba(canvas_png())
        ids = np.where(ids[..., 3] > 0, ids[..., 0], 0).astype(np.int64)
        check(np.array_equal(ids > 0, first[..., 3] > 0), "the id pass covers the pixels the image does")
        if a.reference_pattern:
            for name, canvas in shots.items():
                ref_path = a.reference_pattern.replace("{deg}", name)
                with open(ref_path, "rb") as f:
                    ref = png_rgba(f.read())
                if ref.shape[:2] != canvas.shape[:2]:
                    check(False, f"{ref_path}: {ref.shape[1]}×{ref.shape[0]}, the canvas {canvas.shape[1]}×{canvas.shape[0]}")
                    continue
                mask = interior(ids)
                diff = (canvas[..., :3] - ref[..., :3])[mask]
                mse = float((diff ** 2).mean()) if diff.size else float("nan")
                psnr = math.inf if mse == 0 else 10 * math.log10(255 ** 2 / mse)
                worst = float(np.abs(diff).max()) if diff.size else float("nan")
                result["psnr"][name] = psnr
                check(psnr >= a.min_psnr,
                      f"rotation {name}°: canvas vs prt relight {psnr:.2f} dB over {int(mask.sum())} interior object pixels "
                      f"(limit {a.min_psnr} dB; largest difference {worst:.0f} codes)")

        for _ in range(8):
            driver.execute_script("window.prtView.setRotation(arguments[0])", 37.0)
        times = driver.execute_script("return window.prtView.frameTimes()")
        result["frames"] = len(times)
        result["frame_ms_median"] = sorted(times)[len(times) // 2]
        result["renderer"] = driver.execute_script(
            "const gl = document.createElement('canvas').getContext('webgl2');"
            "const e = gl && gl.getExtension('WEBGL_debug_renderer_info');"
            "return gl ? (e ? gl.getParameter(e.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER)) : null;")
        print(f"frame time: median {result['frame_ms_median']:.1f} ms over {len(times)} frames on {result['renderer']}")
        if a.screenshot:
            driver.execute_script("window.prtView.setRotation(arguments[0])", float(names[0]))
            driver.save_screenshot(a.screenshot)
        severe = [e for e in driver.get_log("browser") if e.get("level") == "SEVERE"]
        check(not severe, "no console error" + (": " + "; ".join(e["message"] for e in severe) if severe else ""))
    finally:
        driver.quit()
    print(json.dumps(result))
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
