"""Peak memory of one stage, per pixel and label: H-LF correspondence and two-view stereo.

    python benchmarks/stage_memory.py correspondence [--size 384,512] [--labels 64]
                                      [--metric auto] [--selection]
    python benchmarks/stage_memory.py stereo [--size 300,400] [--labels 64]
                                      [--metric auto] [--optimizer graphcut]
                                      [--occlusion lr-plane]

Each call measures one case in this process (Linux): the resident size before the stage, the
peak (``VmHWM``, reset through ``/proc/self/clear_refs`` just before), and prints the
difference in bytes per pixel and label (disparity).  A warm-up call compiles the kernels
first.  ``correspondence`` runs ``hlf.correspondence`` on a synthetic 5 x 6 capture
(``procedural_scene(seed=3)``) in one strip and in strips of 128 rows (the figure behind
``tiling._STRIP_BYTES``); ``stereo`` runs ``twoview.stereo`` on a blurred-noise pair whose
right image is contrast-reversed (the figures behind ``cli.PAIR_BYTES_AT_LEAST``).  Run one
case per process, as BENCHMARKS.md does: what an earlier case freed may stay mapped.
"""

from __future__ import annotations

import argparse


def _status(key: str) -> int:
    with open("/proc/self/status", encoding="ascii") as f:
        for line in f:
            if line.startswith(key):
                return int(line.split()[1]) * 1024
    raise RuntimeError(f"no {key} in /proc/self/status (Linux only)")


def _measure(run) -> tuple[int, object]:
    """Bytes the call ``run()`` held at its peak above the resident size before it."""
    before = _status("VmRSS:")
    with open("/proc/self/clear_refs", "w", encoding="ascii") as f:
        f.write("5")  # resets VmHWM to the current resident size
    result = run()
    return _status("VmHWM:") - before, result


def correspondence(H, W, L, metric, selection) -> None:
    from hyperlf import hlf, synthesis

    small = synthesis.procedural_scene(seed=0, rows=3, cols=3, height=32, width=40)
    hlf.depth(small, n_labels=8, metric=metric, view_selection=selection)  # warm-up
    lf = synthesis.procedural_scene(seed=3, rows=5, cols=6, height=H, width=W)
    prob = hlf.prepare(lf, n_labels=L, metric=metric, view_selection=selection)
    for rows in (None, 128):
        strips = None if rows is None else [(a, min(a + rows, H)) for a in range(0, H, rows)]
        held, _ = _measure(lambda: hlf.correspondence(prob, strips=strips))
        per_strip = held / (L * W * (H if rows is None else rows))
        print(f"correspondence {H} x {W}, {L} labels, {metric}, selection {selection}, "
              f"strips of {rows or H} rows: {held / 2**30:.3f} GiB, "
              f"{held / (L * H * W):.1f} B per pixel and label of the image, "
              f"{per_strip:.1f} per pixel and label of a strip")


def stereo(H, W, D, metric, optimizer, occlusion) -> None:
    import cv2
    import numpy as np

    from hyperlf import twoview

    rng = np.random.default_rng(0)
    base = cv2.GaussianBlur(rng.random((H, W + D)).astype(np.float32), (0, 0), 1.5)
    left, right = base[:, D // 2: D // 2 + W].copy(), (1.2 - base[:, :W]).copy()
    twoview.stereo(left[:40, :60], right[:40, :60], (0, 8), metric=metric, optimizer=optimizer,
                   occlusion=occlusion)  # warm-up
    held, res = _measure(lambda: twoview.stereo(left, right, (0, D - 1), metric=metric,
                                                optimizer=optimizer, occlusion=occlusion))
    print(f"stereo {H} x {W}, {D} disparities, {metric} {optimizer} {occlusion}: "
          f"{held / (H * W * D):.1f} B per pixel and disparity, {held / 2**20:.1f} MiB, "
          f"{res.timings['total']:.1f} s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("stage", choices=("correspondence", "stereo"))
    ap.add_argument("--size", default=None, help="H,W (default 384,512 / 300,400)")
    ap.add_argument("--labels", type=int, default=64, help="labels, or disparities of stereo")
    ap.add_argument("--metric", default="auto")
    ap.add_argument("--selection", action="store_true", help="correspondence: view selection")
    ap.add_argument("--optimizer", default="graphcut")
    ap.add_argument("--occlusion", default="lr-plane")
    a = ap.parse_args()
    default = "384,512" if a.stage == "correspondence" else "300,400"
    H, W = (int(v) for v in (a.size or default).split(","))
    if a.stage == "correspondence":
        correspondence(H, W, a.labels, a.metric, a.selection)
    else:
        stereo(H, W, a.labels, a.metric, a.optimizer, a.occlusion)


if __name__ == "__main__":
    main()
