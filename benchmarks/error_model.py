"""How well the boundary policy knows where its fine map is wrong, and whether a learned estimate knows better.

The boundary policy scores a press by the fine map's expected errors within reach (1 - the most probable material's
probability per point). Told the true errors instead (``exploration_fine.py --clairvoyant``) it needs fewer presses;
this script asks how much of that gap an estimate from what the map sees can close. Per scene it runs the boundary
policy's exploration to half a raster's presses and, after 0.1, 0.25 and 0.5 of them, keeps per point of the
planner's fine map: the shipped estimate, features (the top probability's margin over the second, the distance to
the nearest press and to the nearest drawn wall, the cell map's confidence, the share of other labels within 7 mm)
and whether the label is wrong. Models are fitted on the tuning seeds and scored on the report seeds: the AUC of
"this point is wrong", and the greedy capture: the true errors within reach at the point the estimate would press
(the planner's Gaussian of reach, crowding discount and inner part of the cell) over the most any point offers
(the clairvoyant's 1.0).

--in-loop C0,C1,C2,C3,C4 instead explores the tuning seeds to 0.8 of raster's presses with the boundary policy whose
expected errors are the logistic C0 x (1 - top probability) + C1 x margin + C2 x log(1 + mm to press) + C3 x
log(1 + mm to drawn wall) + C4 and prints the rows as ``exploration_fine.py --share 0.8 --json`` does (compare
them with its boundary rows).

Run: .venv/bin/python benchmarks/error_model.py [--tuning-first 0] [--report-first 100024] [--scenes 90] [--jobs 2]
     [--in-loop C0,C1,C2,C3,C4 --json PATH]
"""

from __future__ import annotations

import argparse
import json
import math
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from fine_map_families import trained_scene
from scipy.ndimage import distance_transform_edt, gaussian_filter, uniform_filter
from scipy.spatial import cKDTree
from sklearn.ensemble import HistGradientBoostingClassifier
from sklearn.linear_model import LogisticRegression
from sklearn.metrics import roc_auc_score

from palpate.api import register_policy
from palpate.core.mapping.fine import REACH, REACH_MAX, edges, fine_map, reading_reach
from palpate.core.mapping.grids import new_map
from palpate.core.planning.boundary_seeking import BoundarySeeking
from palpate.core.session.boundaries import fine_truth, training_moduli
from palpate.core.session.explore import MapPostprocessing, apply_press, explore_object
from palpate.core.session.progress import Progress
from palpate.core.world.workspace import object_geometry

SHARES = (0.1, 0.25, 0.5)
FEATURES = ("expected error", "margin", "log(1 + mm to press)", "log(1 + mm to drawn wall)", "cell confidence",
            "other labels within 7 mm")


def snapshot(policy: BoundarySeeking, grid, post, share: float, truth: np.ndarray) -> dict:
    """The planner's fine map after the presses so far: per point features, truth and what the capture needs."""
    _, fine, pts = policy.point_scores(grid, post)
    p = fine.probabilities
    top = np.sort(p, axis=-1)
    lab = np.argmax(p, axis=-1)
    res = fine.resolution
    n = int(round(policy.geometry.cell_size / res))
    presses = np.array(policy._pressed)
    dp = cKDTree(presses).query(pts.reshape(-1, 2))[0].reshape(lab.shape) * 1e3
    drawn = edges(lab, both_sides=True)
    db = distance_transform_edt(~drawn) * res * 1e3 if drawn.any() else np.full(lab.shape, 99.0)
    cell = np.kron(post.probabilities.max(axis=-1), np.ones((n, n)))[: lab.shape[0], : lab.shape[1]]
    m = p.shape[-1]
    w = max(3, int(round(7e-3 / res)))
    same = uniform_filter((lab[..., None] == np.arange(m)).astype(float), size=(w, w, 1), mode="nearest")
    mixed = 1 - np.take_along_axis(same, lab[..., None], -1)[..., 0]
    feats = np.stack([policy.expected_errors(fine), top[..., -1] - top[..., -2], np.log1p(dp), np.log1p(db), cell,
                      mixed], -1).astype(np.float32)
    crowd = np.zeros(lab.shape)
    for xy in presses:
        crowd += np.exp(-np.sum((pts - xy) ** 2, axis=-1) / policy.crowding**2)
    k = np.arange(n) + 0.5 - n / 2
    inner = np.abs(k) <= max(policy.shift * n / 2, 0.5) + 1e-9
    inner = np.tile(inner, lab.shape[0] // n)[:, None] & np.tile(inner, lab.shape[1] // n)[None, :]
    reach = reading_reach(policy.geometry, policy._readings, REACH, max(REACH, REACH_MAX))
    return {"share": share, "features": feats, "wrong": (lab != truth) & (truth >= 0), "known": truth >= 0,
            "sigma": reach / (res * math.sqrt(2)), "crowd": crowd, "inner": inner}


def scene_snapshots(seed: int) -> tuple[str, list[dict]]:
    fs, base, reader, make, training = trained_scene(seed)
    moduli = training_moduli(training.readings)
    cells = int(np.prod(fs.grid_cells))
    geometry = object_geometry(base, base.objects[0])
    truth = fine_truth(base.objects[0], base, fine_map(geometry, new_map(geometry).probabilities, []))
    sc = fs.scenario("boundary", budget=int(np.ceil(max(SHARES) * cells)), fidelity="auto")
    res = explore_object(sc, sc.objects[0], training.memory, make, 7000 + seed, Progress(enabled=False),
                         boundary_reader=reader, moduli=moduli)
    ex = sc.exploration
    grid = new_map(res.geometry)
    settings = MapPostprocessing.of(ex)
    policy = BoundarySeeking(training.memory, res.geometry, moduli)
    at = {max(1, int(round(q * cells))): q for q in SHARES}
    out = []
    for k, s in enumerate(res.steps, start=1):
        apply_press(grid, s.result, training.memory, None, fallback_xy=s.target, calibration=ex.calibration)
        policy.observe(s.result.location, s.boundary)
        if k in at:
            out.append(snapshot(policy, grid, settings.apply(grid, ex.calibration), at[k], truth))
    return fs.family, out


def capture(snap: dict, estimate: np.ndarray) -> float | None:
    """True errors within reach where ``estimate`` would press, over the most any point offers (None: no error)."""
    def within(x):
        return gaussian_filter(x, snap["sigma"], mode="constant", truncate=3.0) / (1 + snap["crowd"])
    truth = np.where(snap["inner"], within(snap["wrong"].astype(float)), -1.0)
    if truth.max() <= 0:
        return None
    est = np.where(snap["inner"], within(estimate), -np.inf)
    return float(truth.flat[int(np.argmax(est))] / truth.max())


def table(snaps: list[dict], models: dict) -> None:
    X = np.concatenate([s["features"][s["known"]] for s in snaps])
    y = np.concatenate([s["wrong"][s["known"]] for s in snaps])
    print(f"{'estimate':34} AUC    capture " + " ".join(f"{q:>5g}" for q in SHARES) + "   all")
    for name, f in models.items():
        caps = {q: [] for q in SHARES}
        for s in snaps:
            flat = s["features"].reshape(-1, len(FEATURES))
            c = capture(s, f(flat).reshape(s["wrong"].shape) * s["known"])
            if c is not None:
                caps[s["share"]].append(c)
        every = [c for v in caps.values() for c in v]
        print(f"{name:34} {roc_auc_score(y, f(X)):.3f}         " + " ".join(f"{np.mean(caps[q]):5.3f}" for q in SHARES)
              + f" {np.mean(every):5.3f}")


class LearnedBoundary(BoundarySeeking):
    """The boundary policy with a logistic estimate of where its fine map is wrong (``--in-loop``)."""

    coefficients: tuple = (0.0, 0.0, 0.0, 0.0, 0.0)

    def expected_errors(self, fine) -> np.ndarray:
        p = np.sort(fine.probabilities, axis=-1)
        u = 1.0 - p[..., -1]
        if not self._pressed or p.shape[-1] < 2:
            return u
        dp = cKDTree(np.array(self._pressed)).query(fine.centres().reshape(-1, 2))[0].reshape(u.shape) * 1e3
        drawn = edges(np.argmax(fine.probabilities, axis=-1), both_sides=True)
        db = distance_transform_edt(~drawn) * fine.resolution * 1e3 if drawn.any() else np.full(u.shape, 99.0)
        c = self.coefficients
        z = c[0] * u + c[1] * (p[..., -1] - p[..., -2]) + c[2] * np.log1p(dp) + c[3] * np.log1p(db) + c[4]
        return 1.0 / (1.0 + np.exp(-z))


def learned_rows(seed: int, coefficients: tuple) -> list[dict]:
    from exploration_fine import scene_rows

    def factory(ctx):
        p = LearnedBoundary(ctx.memory, ctx.geometry, ctx.moduli, seed=ctx.seed)
        p.coefficients = coefficients
        return p

    register_policy("boundary_learned", factory, replace=True)
    return scene_rows(seed, ("boundary_learned",), share=0.8)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--tuning-first", type=int, default=0)
    parser.add_argument("--report-first", type=int, default=100024)
    parser.add_argument("--scenes", type=int, default=90)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--in-loop", default=None)
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    t0 = time.time()
    tuning = list(range(args.tuning_first, args.tuning_first + args.scenes))
    if args.in_loop:
        coefficients = tuple(float(v) for v in args.in_loop.split(","))
        with ProcessPoolExecutor(args.jobs) as pool:
            rows = [r for part in pool.map(learned_rows, tuning, [coefficients] * len(tuning)) for r in part]
        if args.json:
            with open(args.json, "w") as fh:
                json.dump(rows, fh, indent=1)
        ratios = [(r["to_target"] or r["cells"] + 1) / r["cells"] for r in rows]
        print(f"{len(rows)} scenes: presses to 95% / raster's median {np.median(ratios):.3f}, "
              f"p95 {np.percentile(ratios, 95):.3f}; {time.time() - t0:.0f} s wall")
        return
    report = list(range(args.report_first, args.report_first + args.scenes))
    with ProcessPoolExecutor(args.jobs) as pool:
        done = dict(zip(tuning + report, pool.map(scene_snapshots, tuning + report), strict=True))
    train = [s for seed in tuning for s in done[seed][1]]
    test = [s for seed in report for s in done[seed][1]]
    X = np.concatenate([s["features"][s["known"]] for s in train])
    y = np.concatenate([s["wrong"][s["known"]] for s in train])
    print(f"tuning seeds {tuning[0]}-{tuning[-1]}: {len(y)} points ({y.mean():.3f} wrong); report seeds "
          f"{report[0]}-{report[-1]}")
    models = {"shipped (1 - top probability)": lambda F: F[:, 0]}
    for name, cols in (("logistic: estimate, margin", [0, 1]), ("logistic: + distances", [0, 1, 2, 3]),
                       ("logistic: all six", list(range(len(FEATURES))))):
        lr = LogisticRegression(max_iter=500).fit(X[:, cols], y)
        models[name] = (lambda F, lr=lr, cols=cols: lr.predict_proba(F[:, cols])[:, 1])
        terms = ", ".join(f"{FEATURES[c]} {v:+.3f}" for c, v in zip(cols, lr.coef_[0], strict=True))
        print(f"  {name}: coefficients {terms}, intercept {lr.intercept_[0]:+.3f}")
    sub = np.random.default_rng(0).choice(len(y), min(len(y), 400_000), replace=False)
    hgb = HistGradientBoostingClassifier(max_iter=200, random_state=0).fit(X[sub], y[sub])
    models["gradient boosting: all six"] = lambda F: hgb.predict_proba(F)[:, 1]
    print("report seeds:")
    table(test, models)
    print(f"{time.time() - t0:.0f} s wall")


if __name__ == "__main__":
    main()
