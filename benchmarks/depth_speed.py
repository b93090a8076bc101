"""Wall time per stage of the default H-LF depth on one capture (issue 13's first figure).

    hyperlf -q synth hci $HYPERLF_DATA/hci4d/antinous -o antinous
    /usr/bin/time -f "%e s %M KB" python benchmarks/depth_speed.py antinous --labels 64

A small warm-up call first compiles (or loads from numba's cache) every kernel, so the stage
timings are those of the run itself; ``/usr/bin/time`` gives the whole process and its peak
memory.  ``--compare FILE.npy`` checks the disparity bit for bit against a saved one
(``--save FILE.npy`` writes it), which is how a speed change is shown to change nothing.
"""

from __future__ import annotations

import argparse

import numpy as np


def main() -> None:
    from hyperlf.formats import load_lightfield
    from hyperlf.hlf import depth
    from hyperlf.synthesis import procedural_scene

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("capture", help="capture folder or .h5")
    ap.add_argument("--labels", type=int, default=64)
    ap.add_argument("--save", help="write the disparity to this .npy")
    ap.add_argument("--compare", help="compare the disparity with this .npy")
    a = ap.parse_args()
    lf = load_lightfield(a.capture)
    depth(procedural_scene(seed=0, rows=3, cols=3, height=32, width=40), n_labels=8)  # warm-up
    res = depth(lf, n_labels=a.labels)
    print(" ".join(f"{k}={v:.1f}" for k, v in res.timings.items()))
    if a.save:
        np.save(a.save, res.disparity)
    if a.compare:
        ref = np.load(a.compare)
        same = np.array_equal(ref, res.disparity)
        print(f"identical to {a.compare}: {same}"
              + ("" if same else f" (max |diff| {np.nanmax(np.abs(ref - res.disparity)):.3g})"))


if __name__ == "__main__":
    main()
