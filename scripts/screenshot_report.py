"""Open a run's ``report.html`` in headless Chromium and save a full-page screenshot.

    hlaid demo --out hlaid-demo
    python scripts/screenshot_report.py hlaid-demo -o hlaid-demo/report.png

Checks first that every figure the report should carry is embedded as a valid PNG (loops,
stiffness, replay; IDA curves, fragility and exceedance when the run had an IDA), then renders
the page (Debian: ``apt install chromium``) and checks the screenshot is not blank.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from hlaid.run.report import FIGURES, embedded_figures, screenshot


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run_dir", nargs="?", default="hlaid-demo", help="run folder holding report.html")
    ap.add_argument("-o", "--out", default=None, help="PNG path (default RUN_DIR/report.png)")
    ap.add_argument("--browser", default=None, help="browser executable (default: chromium, then others)")
    args = ap.parse_args(argv)
    run = Path(args.run_dir)
    report = run / "report.html"
    figs = embedded_figures(report)
    expected = [Path(rel).name for rel, _ in FIGURES if (run / rel).exists()]
    missing = sorted(set(expected) - {alt for alt, _ in figs})
    for alt, n in figs:
        print(f"embedded {alt}: {n / 1024:.0f} KiB")
    if missing:
        print(f"error: {report}: figures not embedded: {', '.join(missing)}", file=sys.stderr)
        return 1
    png = screenshot(report, args.out or run / "report.png", browser=args.browser)
    import matplotlib.image as mpimg
    img = mpimg.imread(png)
    spread = float(np.ptp(img[..., :3]))
    print(f"screenshot {png}: {img.shape[1]} x {img.shape[0]} px, {len(figs)} figures, colour range {spread:.2f}")
    if spread < 0.1:
        print(f"error: {png}: the screenshot is blank", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
