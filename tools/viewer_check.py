#!/usr/bin/env python3
"""Opens a prt report's index.html in headless Chromium (Selenium) and checks the viewer.

    python3 tools/viewer_check.py OUT/index.html [--screenshot viewer.png]
        [--screenshot-charts charts.png] [--max-load-ms 1000] [--max-mb 20]

Checks, each printed, and exit status 1 when one fails:
- the page is at most --max-mb megabytes and loads from file:// (no network) within
  --max-load-ms milliseconds (navigation start to the load event, as the browser measures it);
- the browser console holds no error (SEVERE entry) and the viewer script ran (`prtViewer`);
- the displayed pixels (a checksum of the canvas) change when the exposure slider moves, when
  A is switched to another image, in the |A - B| false-colour view, and with another tone
  curve; the pixel probe fills with one row per image when the mouse moves over the image;
- clicking a table header sorts that table;
- every chart is drawn (SVG with points or bars) and hovering a point shows its tooltip.

Needs Debian's chromium and chromium-driver and PyPI's selenium
(tools/requirements-browser.txt).
"""

import argparse
import json
import os
import sys
import time


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("page")
    ap.add_argument("--screenshot")
    ap.add_argument("--screenshot-charts")
    ap.add_argument("--max-load-ms", type=float, default=1000.0)
    ap.add_argument("--max-mb", type=float, default=20.0)
    ap.add_argument("--chromium", default=os.environ.get("CHROMIUM", "/usr/bin/chromium"))
    ap.add_argument("--chromedriver", default=os.environ.get("CHROMEDRIVER", "/usr/bin/chromedriver"))
    a = ap.parse_args()

    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import Select

    path = os.path.abspath(a.page)
    failures = []

    def check(ok, what):
        print(("ok   " if ok else "FAIL ") + what)
        if not ok:
            failures.append(what)

    size_mb = os.path.getsize(path) / 1e6
    check(size_mb <= a.max_mb, f"page size {size_mb:.2f} MB (limit {a.max_mb} MB)")

    opts = webdriver.ChromeOptions()
    opts.binary_location = a.chromium
    for flag in ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic",
                 "--no-first-run", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--window-size=1400,1100"]:
        opts.add_argument(flag)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(a.chromedriver), options=opts)
    try:
        driver.get("file://" + path)
        for _ in range(100):
            if driver.execute_script("return !!(window.prtViewer && window.prtViewer.ready)"):
                break
            time.sleep(0.05)
        ready = driver.execute_script("return !!(window.prtViewer && window.prtViewer.ready)")
        check(ready, "the viewer script ran (window.prtViewer.ready)")
        load_ms = driver.execute_script(
            "const n = performance.getEntriesByType('navigation')[0];"
            "return n ? n.loadEventEnd - n.startTime : null;")
        check(load_ms is not None and load_ms <= a.max_load_ms,
              f"load time {load_ms:.0f} ms (limit {a.max_load_ms:.0f} ms)" if load_ms is not None
              else "load time measured")
        if not ready:
            raise SystemExit(1)

        checksum = lambda: driver.execute_script("return window.prtViewer.checksum()")
        images = driver.execute_script("return window.prtViewer.images")
        check(len(images) >= 2, f"{len(images)} images offered: {', '.join(images[:4])}, ...")

        def set_range(elem_id, value):
            driver.execute_script(
                "const e = document.getElementById(arguments[0]); e.value = arguments[1];"
                "e.dispatchEvent(new Event('input', {bubbles: true}));", elem_id, str(value))

        c0 = checksum()
        set_range("ev", 2.5)
        c1 = checksum()
        check(c1 != c0, "moving the exposure to +2.5 EV changes the displayed pixels")
        set_range("ev", 0)
        check(checksum() == c0, "moving it back to 0 EV restores them exactly")

        pick_a = Select(driver.find_element(By.ID, "pick-a"))
        pick_a.select_by_index(len(images) - 1)
        c2 = checksum()
        check(c2 != c0, f"choosing A = '{images[-1]}' changes the displayed pixels")
        Select(driver.find_element(By.ID, "tone")).select_by_value("aces")
        check(checksum() != c2, "another tone curve (ACES) changes them")
        Select(driver.find_element(By.ID, "mode")).select_by_value("diff")
        c3 = checksum()
        legend = driver.find_element(By.ID, "legend")
        check(c3 != c2 and legend.is_displayed(),
              "the |A - B| false-colour view draws and shows its scale: "
              + driver.find_element(By.ID, "legend-max").text)
        Select(driver.find_element(By.ID, "mode")).select_by_value("wipe")
        check(checksum() not in (c2, c3), "the wipe view draws A and B side by side")
        Select(driver.find_element(By.ID, "mode")).select_by_value("a")

        canvas = driver.find_element(By.ID, "view")
        ActionChains(driver).move_to_element(canvas).move_by_offset(5, 5).perform()
        rows = driver.find_elements(By.CSS_SELECTOR, "#probe-body tr")
        check(len(rows) == len(images),
              f"the pixel probe lists every image at the cursor ({len(rows)} rows, "
              + driver.find_element(By.ID, "probe-xy").text + ")")

        # Sorting: the largest sortable table, by its second column, up then down.
        tables = driver.find_elements(By.CSS_SELECTOR, "table.sortable")
        if tables:
            t = max(tables, key=lambda t: len(t.find_elements(By.TAG_NAME, "tr")))
            header = t.find_elements(By.TAG_NAME, "th")[1]

            def column():
                vals = []
                for r in t.find_elements(By.TAG_NAME, "tr")[1:]:
                    text = r.find_elements(By.TAG_NAME, "td")[1].text.replace("×", "").strip()
                    try:
                        vals.append(float("inf") if text == "∞" else float(text))
                    except ValueError:
                        vals.append(text)
                return vals

            header.click()
            up = column()
            header.click()
            down = column()
            numeric = all(isinstance(v, float) for v in up)
            ok = (up == sorted(up) and down == sorted(down, reverse=True)) if numeric else up != down
            check(ok and len(up) > 1,
                  f"clicking '{header.text}' sorts its {len(up)}-row table up, then down")
        charts = driver.find_elements(By.CSS_SELECTOR, "svg.chart")
        marks = driver.find_elements(By.CSS_SELECTOR, "svg.chart .point, svg.chart .bar")
        check(len(charts) >= 2 and len(marks) > 0, f"{len(charts)} charts with {len(marks)} points/bars")
        if marks:
            driver.execute_script("arguments[0].scrollIntoView()", marks[0])
            ActionChains(driver).move_to_element(marks[0]).perform()
            tip = driver.find_element(By.ID, "tooltip")
            check(tip.is_displayed() and "order" in tip.text,
                  "hovering a point shows its row: " + tip.text.replace("\n", " | ")[:90])

        logs = driver.get_log("browser")
        errors = [l for l in logs if l.get("level") == "SEVERE"]
        check(not errors, "no console error" + ("" if not errors else ": " + json.dumps(errors)[:300]))

        if a.screenshot:
            driver.execute_script("window.scrollTo(0, 0)")
            Select(driver.find_element(By.ID, "mode")).select_by_value("wipe")
            driver.save_screenshot(a.screenshot)
            print("screenshot:", a.screenshot)
        if a.screenshot_charts:
            driver.execute_script("document.getElementById('charts').scrollIntoView()")
            marks = driver.find_elements(By.CSS_SELECTOR, "svg.chart .point")
            if len(marks) > 12:
                ActionChains(driver).move_to_element(marks[12]).perform()
            driver.save_screenshot(a.screenshot_charts)
            print("screenshot:", a.screenshot_charts)
    finally:
        driver.quit()
    if failures:
        print(f"{len(failures)} check(s) failed", file=sys.stderr)
        sys.exit(1)
    print("all checks passed")


if __name__ == "__main__":
    main()
