"""Screenshots of the HTML viewer for docs/viewer/: ``python experiments/viewer_screenshots.py``.

For each result ``docs/datasets/NAME.json`` (default: bunny, duck, butterfly) it writes the
viewer page with the bundled dataset's points, normals and faces, opens it in headless
chromium (selenium + chromedriver) and saves ``OUT/NAME.png`` at the selected degree and
``OUT/NAME-degree-G.png`` at the degree given with ``--also NAME=G`` (e.g. one with a
spurious component). Page sizes are printed. Pages go to a temporary folder unless
``--keep-html``.

    python experiments/viewer_screenshots.py [NAME ...] [-o docs/viewer] [--also bunny=8]
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's ipfit, not an installed one

REPO = Path(__file__).resolve().parents[1]
UP = {"bunny": "y", "apple": "y"}  # the bundled scans that are y-up


def _driver(width: int, height: int):
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = shutil.which("chromium") or "/usr/bin/chromium"
    for arg in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", f"--window-size={width},{height}",
                "--enable-unsafe-swiftshader", "--hide-scrollbars"):
        options.add_argument(arg)
    return webdriver.Chrome(service=Service(shutil.which("chromedriver") or "/usr/bin/chromedriver"), options=options)


def _show_degree(driver, degree: int) -> None:
    # The same update the slider's step makes, so the page state matches a user's click.
    driver.execute_script(
        "var gd = document.querySelector('.js-plotly-plot');"
        "var steps = gd.layout.sliders[0].steps;"
        "var i = steps.findIndex(s => s.label === String(arguments[0]));"
        "Plotly.update(gd, steps[i].args[0], steps[i].args[1], steps[i].args[2]);"
        "Plotly.relayout(gd, {'sliders[0].active': i});", degree)


def main(argv=None) -> int:
    from ipfit import load_dataset
    from ipfit.datasets.bundled import dataset_faces
    from ipfit.viz.viewer import write_html

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", default=["bunny", "duck", "butterfly"])
    parser.add_argument("-o", "--out", type=Path, default=REPO / "docs" / "viewer")
    parser.add_argument("--also", action="append", metavar="NAME=G",
                        help="another screenshot of NAME at degree G (default bunny=6 duck=8: spurious parts)")
    parser.add_argument("--size", type=int, nargs=2, default=(1400, 820), metavar=("W", "H"))
    parser.add_argument("--keep-html", action="store_true", help="keep the pages beside the screenshots")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    extra = {}
    for item in args.also or ["bunny=6", "duck=8"]:
        name, degree = item.split("=")
        extra.setdefault(name, []).append(int(degree))
    driver = _driver(*args.size)
    try:
        with tempfile.TemporaryDirectory() as tmp:
            for name in args.names:
                data = json.loads((REPO / "docs" / "datasets" / f"{name}.json").read_text())
                cloud = load_dataset(name)
                page = (args.out if args.keep_html else Path(tmp)) / f"{name}.html"
                t0 = time.perf_counter()
                write_html(data, cloud.points, page, faces=dataset_faces(name), normals=cloud.normals,
                           up=UP.get(name, "z"), title=name)
                print(f"{name}: {page.stat().st_size / 1e6:.1f} MB page, {time.perf_counter() - t0:.1f} s to write")
                driver.get(page.resolve().as_uri())
                time.sleep(3)
                driver.save_screenshot(str(args.out / f"{name}.png"))
                for degree in extra.get(name, []):
                    _show_degree(driver, degree)
                    time.sleep(2)
                    driver.save_screenshot(str(args.out / f"{name}-degree-{degree}.png"))
    finally:
        driver.quit()
    return 0


if __name__ == "__main__":
    sys.exit(main())
