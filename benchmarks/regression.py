"""Behaviour-preserving refactors: run the public computations on small inputs and compare
every array bit for bit with a recording made before the change.

    python benchmarks/regression.py save before.npz      # on the commit before the change
    python benchmarks/regression.py compare before.npz   # after; ends "0 not bit-identical"

About 180 arrays (every cost volume in both implementations, two-view stereo for every cost x
optimiser, every light-field cost, H-LF depth with every cue and optimiser, completion,
rendering, the baselines, warp and the regularisers) in under a minute on 2 cores.  Run both
with the same environment (``HYPERLF_DATA`` set or unset in both: it changes the synthetic
scenes' reflectances) and the same number of threads.
"""
import sys, time, warnings
import numpy as np
warnings.filterwarnings("ignore")

def cases():
    from hyperlf import synthesis, costs, twoview, hlf, completion, render, baselines, warp, regularisers
    rng = np.random.default_rng(0)
    lf = synthesis.procedural_scene(seed=1, rows=3, cols=4, height=40, width=48, disparity_range=(-1.5, 1.5))
    yield "lf_views", lf.views
    # integer-shift pair with real structure
    base = rng.random((36, 52)).astype(np.float32)
    import cv2
    base = cv2.GaussianBlur(base, (0, 0), 1.2) + 0.05
    Lp = base[:, 6:46].copy(); Rp = (1.3 - base[:, 4:44]).copy()
    for m in ["ssd", "ncc", "rsncc", "census", "bwncc", "bwncc-paper", "fused", "census-rsncc"]:
        for impl in ["numpy", "numba"]:
            if m == "ssd" and impl == "numba":
                continue
            yield f"cv_{m}_{impl}", costs.cost_volume(Lp, Rp, 0, 5, metric=m, impl=impl)
    for m in ["auto", "ncc", "census", "rsncc", "ssd", "bwncc", "fused"]:
        for opt in ["graphcut", "sgm", "wta"]:
            r = twoview.stereo(Lp, Rp, (0, 5), metric=m, optimizer=opt, subpixel=(opt == "sgm"))
            yield f"st_{m}_{opt}_disp", r.disparity
            yield f"st_{m}_{opt}_conf", r.confidence
    r = twoview.stereo(Lp, Rp, (0, 5), optimizer="graphcut", occlusion="none", params={"levels": 0})
    yield "st_gc_l0", r.disparity
    labels = hlf.make_labels(-1.5, 1.5, 7)
    for m in hlf.CORR_METRICS:
        C, v = hlf.view_costs(lf.views[1, 1], lf.views[0, 3], (1.0, -1.0), labels, m)
        yield f"vc_{m}", C
        yield f"vc_{m}_valid", v
    lab = 9
    for name, kw in [("default", {}), ("vs", dict(view_selection=True)), ("split", dict(occlusion_split=True)),
                     ("vs_split", dict(view_selection=True, occlusion_split=True)),
                     ("tv", dict(defocus="tv")), ("paper", dict(defocus="paper")), ("sgm", dict(optimizer="sgm")),
                     ("wta", dict(optimizer="wta")), ("ncc", dict(metric="ncc")), ("census", dict(metric="census")),
                     ("rsncc", dict(metric="rsncc")), ("bwnccp", dict(metric="bwncc-paper")),
                     ("occw", dict(params=hlf.DepthParams(occlusion_weight=0.3))),
                     ("norefine", dict(params=hlf.DepthParams(refine=False, median_radius=0))),
                     ("numpy", dict(params=hlf.DepthParams(impl="numpy")))]:
        res = hlf.depth(lf, n_labels=lab, save_intermediate=True, **kw)
        yield f"d_{name}_disp", res.disparity
        yield f"d_{name}_conf", res.confidence
        yield f"d_{name}_fc", res.f_c
        if res.f_d is not None:
            yield f"d_{name}_fd", res.f_d
        yield f"d_{name}_U", res.intermediate["unary"]
    # the texture weight, coarse prior and weak planes (on for captures from cameras): a flat,
    # noisy band over most of the views (the procedural texture, which grows under binning,
    # reads as noise-free to imageops.noise_sigma once it holds most pixels; BENCHMARKS), on
    # views large enough for the planes' tiles
    big = synthesis.procedural_scene(seed=2, rows=3, cols=3, height=96, width=112,
                                     disparity_range=(-1.5, 1.5))
    noisy = big.views.copy()
    noisy[:, :, 30:] = 0.5
    noisy += 0.004 * np.random.default_rng(5).standard_normal(noisy.shape)
    cam = big.replace(views=noisy.astype(np.float32),
                      metadata={**big.metadata, "calibration": {"mode": "plane"}})
    res = hlf.depth(cam, n_labels=17, save_intermediate=True)
    yield "d_camera_disp", res.disparity
    yield "d_camera_conf", res.confidence
    yield "d_camera_weight", res.intermediate["texture_weight"]
    gt = lf.gt_disparity[lf.reference]
    cr = completion.complete(lf, gt)
    yield "comp_cube", cr.cube; yield "comp_mask", cr.mask
    cr = completion.complete(lf, None if gt is None else gt, optimizer="graphcut")
    yield "comp_gc_cube", cr.cube
    cr = completion.complete(lf, gt, infer=False, optimizer="wta")
    yield "comp_wta_cube", cr.cube
    nr = completion.naive_completion(lf, gt)
    yield "naive_cube", nr.cube; yield "naive_mask", nr.mask
    cube = cr.cube
    wl = cr.wavelengths
    yield "emu", render.emulate_camera(cube[1, 2], wl)
    yield "emu_srgb", render.emulate_camera(cube[1, 2], wl, output="srgb")
    offs = lf.offsets
    yield "refocus", render.refocus(cube, offs, disparity=0.7, wavelengths=wl)
    yield "refocus_map", render.refocus(cube, offs, disparity=gt, wavelengths=wl)
    yield "stack", np.asarray(render.focal_stack(cube, offs, disparities=(-1.0, 0.25), wavelengths=wl))
    yield "allfocus", render.all_focus(cube, offs, disparity=gt, wavelengths=wl)
    yield "allfocus_views", render.all_focus(cube, offs, disparity=gt, wavelengths=wl,
                                             view_disparities=lf.gt_disparity, occlusion="views")
    yield "allfocus_none", render.all_focus(cube, offs, disparity=gt, wavelengths=wl,
                                            occlusion="none")
    yield "refocus_lf", render.refocus(lf, None, 0.5)
    yield "allfocus_lf", render.all_focus(lf, disparity=gt)
    m = np.ones(cube.shape[:2] + cube.shape[3:], bool); m[0, 0, :5] = False
    cn = cube.copy(); cn[1, 1, 0, 3, 4] = np.nan
    yield "refocus_masked", render.refocus(cn, offs, disparity=0.3, wavelengths=wl, mask=m,
                                           aperture=1.0)
    yield "refocus_band", render.refocus(cube, offs, 0.2, profile=float(wl[2]), wavelengths=wl)
    yield "allfocus_lf_masked", render.all_focus(lf, disparity=gt, mask=m, aperture=1.5)
    for meth in ["tao2013", "wang2015", "lin2015"]:
        b = getattr(baselines, meth)(lf, n_labels=lab)
        yield f"bl_{meth}", b.disparity
    x = rng.uniform(-2, 50, (20, 30)); y = rng.uniform(-2, 42, (20, 30))
    v, ok = warp.sample_bilinear(lf.views[0, 0], x, y)
    yield "warp_sb", v; yield "warp_sb_ok", ok
    yield "warp_shift", warp.shift_image(lf.views[0, 0], 0.3, -1.7)[0]
    yield "warp_ref", warp.warp_to_reference(lf.views[0, 0], gt, (1.0, -1.0))[0]
    yield "warp_fwd", warp.forward_warp_disparity(gt, (1.0, -1.0))
    yield "shiftmap", hlf.shift_map(lf.views[0, 0], 0.4, -0.6, 2)[0]
    Iv = lf.views.reshape(-1, *lf.views.shape[2:]) / lf.views.max()
    ov, wv = lf.offsets.reshape(-1, 2), lf.wavelengths.ravel()
    vmask = np.ones(Iv.shape, bool); vmask[2, :4, :6] = False
    fc = lf.gt_disparity[lf.reference]
    for tag, kw in [("label", {}), ("pixel", dict(lambda_r="per_pixel", f_c=fc)),
                    ("fixed", dict(lambda_r=550.0)), ("flat", dict(prior="flat")),
                    ("pixel_valid", dict(lambda_r="per_pixel", f_c=fc, valid=vmask)),
                    ("label_valid", dict(valid=vmask))]:
        Dv, lam = hlf.defocus_volume(Iv, ov, wv, labels, **kw)
        yield f"defocus_{tag}", Dv
        if lam is not None:
            yield f"defocus_{tag}_lambda", lam
    c = rng.random((6, 20, 24)).astype(np.float32)
    yield "reg_sgm", regularisers.sgm(c, 0.2, 1.0)
    yield "reg_gc", regularisers.graphcut(c, weight=0.3, truncation=2.0)
    yield "reg_gcm", regularisers.graphcut_multiscale(c, weight=0.3, truncation=2.0)
    yield "reg_wm", regularisers.weighted_median(c[0] * 5, c[1], 3, 0.1)

def _save(path):
    t0 = time.time()
    out = {k: np.asarray(v) for k, v in cases()}
    np.savez_compressed(path, **out)
    print(f"saved {len(out)} arrays in {time.time()-t0:.0f}s")
    return 0


def _difference(k, r, v):
    """None when ``v`` is ``r`` bit for bit (NaN where NaN), else a line saying how not."""
    if r.shape != v.shape:
        return f"SHAPE {k} {r.shape} {v.shape}"
    if np.array_equal(r, v, equal_nan=True):
        return None
    d = np.nanmax(np.abs(r.astype(np.float64) - v.astype(np.float64))) if r.size else 0
    nd = int((~((r == v) | (np.isnan(r.astype(float)) & np.isnan(v.astype(float))))).sum())
    return f"DIFF {k}: max abs {d:.3g}, {nd}/{r.size} entries differ"


def _compare(path):
    t0 = time.time()
    ref = np.load(path)
    seen, bad, inexact = set(), 0, 0
    for k, v in cases():
        seen.add(k)
        v = np.asarray(v)
        if k not in ref:
            print("NEW", k)
            continue
        if ref[k].dtype != v.dtype:
            print("DTYPE", k, ref[k].dtype, v.dtype)
        line = _difference(k, ref[k], v)
        if line:
            print(line)
            bad += line.startswith("SHAPE")
            inexact += line.startswith("DIFF")
    missing = sorted(set(ref.files) - seen)
    for k in missing:
        print("MISSING", k)
    print(f"compared {len(seen)} arrays in {time.time()-t0:.0f}s: {bad} shape errors, "
          f"{inexact} not bit-identical")
    return 1 if bad or inexact or missing else 0


def main(argv=None):
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter,
                                     epilog="exit status: 0 all bit-identical (or saved), 1 "
                                            "something differs, 2 a usage error")
    parser.add_argument("mode", choices=["save", "compare"],
                        help="save a recording, or compare this code with one")
    parser.add_argument("path", help="the recording (.npz)")
    args = parser.parse_args(argv)
    return _save(args.path) if args.mode == "save" else _compare(args.path)


if __name__ == "__main__":
    sys.exit(main())
