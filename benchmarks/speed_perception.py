"""Per-press perception against a plain numpy reference of the same arithmetic, timed in one run.

Run: .venv/bin/python benchmarks/speed_perception.py [--quick] [--repeats N]

What is timed is what a run does with every press: the raw streams of one press (taxel frames and pose samples)
-> sync -> contact features -> segmentation -> the two 3/2-power fits -> the haptic-memory posterior -> the
update of one 2-D map cell (``perceive_press`` + ``apply_press``). The reference below does the same arithmetic
with as few numpy calls as it takes and no validation, dataclasses or options; before any timing it must give the
library's posterior and map cell bit for bit on every press, so the ratio compares equal work.

The presses come from the analytic simulation (three materials, human-like variability, ~41 taxel frames and
~25 pose samples each). The memory is trained on presses of seeds 0-2; the timed presses come from seeds 100-102.
The two paths are interleaved press by press (which goes first alternates), so load on the machine hits both
alike; CPU time per press is reported as the median over all repetitions, and the ratio of the medians. A second
table times each stage of the palpate path on its own, the voxel path, and PressLog.add (laying a press on the
run's timeline) against rebuilding every frame and pose dataclass, which is what it did before.
"""

from __future__ import annotations

import argparse
import math
import statistics
import time
from dataclasses import replace

import numpy as np

from palpate.core.mapping.grids import Grid2D, VoxelGrid
from palpate.core.perception.fit import fit_press
from palpate.core.perception.gaussian import GaussianFactors
from palpate.core.perception.layered_memory import LayeredMemory
from palpate.core.perception.memory import HapticMemory
from palpate.core.perception.pipeline import presses_from_recording
from palpate.core.perception.press import perceive_press
from palpate.core.session.explore import apply_press
from palpate.core.session.press_log import PressLog
from palpate.core.session.sources import PressTarget
from palpate.core.world.scene import Material, ObjectSpec, Scene
from palpate.sim.source import SimSource

MATERIALS = {"soft": 20e3, "medium": 115e3, "hard": 450e3}
# Press speed, m/s, that gives ~41 taxel frames (50 Hz) and ~25 poses (30 Hz) per press on these materials.
SPEED = 0.027
TARGET = 1.3


def recordings(seed0: int, n_per: int) -> list:
    out = []
    for i, (name, young) in enumerate(MATERIALS.items()):
        block = ObjectSpec(name, "box", (0.08, 0.08, 0.04), (0.0, 0.0), Material(name, young, 0.4))
        src = SimSource(Scene((block,)), fidelity="analytic", seed=seed0 + i, variability="human")
        out += [(name, src.press(PressTarget(0.0, 0.0, speed=SPEED))) for _ in range(n_per)]
    return out


# ---- the reference: the library's arithmetic, nothing else ------------------------------------------------------

def _percentile_linear(xs: np.ndarray, q: float) -> float:
    """np.percentile(x, q) of sorted xs, the same floats (numpy's 'linear' method and its _lerp)."""
    vi = (len(xs) - 1) * (q / 100)
    lo = math.floor(vi)
    hi = min(lo + 1, len(xs) - 1)
    g = vi - lo
    a, b = float(xs[lo]), float(xs[hi])
    return b - (b - a) * (1 - g) if g >= 0.5 else a + (b - a) * g


def _median_sorted(xs: np.ndarray) -> float:
    n = len(xs)
    h = n // 2
    return float(xs[h]) if n % 2 else (float(xs[h - 1]) + float(xs[h])) / 2.0


class Reference:
    """Everything fixed across presses, as plain arrays."""

    def __init__(self, memory: HapticMemory, grid: Grid2D):
        fn = GaussianFactors.of(memory.means_N, memory.covs_N)
        fa = GaussianFactors.of(memory.means_A, memory.covs_A)
        self.means = (fn.means, fa.means)
        self.chol_inv = (fn.chol_inv, fa.chol_inv)
        self.log_det = (fn.log_det, fa.log_det)
        self.log_2pi = 2 * math.log(2.0 * math.pi)
        self.log_prior = np.log(memory.prior)
        self.p = np.array(grid.probabilities)
        self.origin, self.cell = grid.origin, grid.cell_size
        self.log_p_min = math.log(grid.p_min)

    def press(self, frames, poses) -> np.ndarray:
        """Posterior of one press's streams, fused into its map cell; returns the posterior."""
        n = len(frames)
        t = np.fromiter([f.t for f in frames], float, n)
        counts = np.array([f.counts for f in frames])
        area = frames[0].sensel_area
        tp = np.fromiter([p.t for p in poses], float, len(poses))
        pos = np.array([p.position for p in poses])
        # sync: pose interpolated at taxel times; a frame is valid inside the pose span and off a pose gap
        i = np.searchsorted(tp, t, "right") - 1
        np.clip(i, 0, len(tp) - 2, out=i)
        t0, t1 = tp[i], tp[i + 1]
        s = (t - t0) / (t1 - t0)
        np.clip(s, 0.0, 1.0, out=s)
        p0 = pos[i]
        xyz = p0 + s[:, None] * (pos[i + 1] - p0)
        valid = (t >= tp[0]) & (t <= tp[-1]) & ~(((t1 - t0) > 0.1) & (s != 0.0) & (s != 1.0))
        # features (noise threshold 0: every count is active)
        flat = counts.reshape(n, -1)
        c_a = np.count_nonzero(flat, axis=1) * area
        c_p = flat.sum(axis=1, dtype=np.int64).astype(float)
        h = xyz[:, 2]
        # thresholds from the data's noise
        cs = np.sort(c_p)
        baseline = _percentile_linear(cs, 5)
        d1 = c_p[1:] - c_p[:-1]
        d2 = np.sort(d1[1:] - d1[:-1])
        mad = np.sort(np.abs(d2 - _median_sorted(d2)))
        noise = 1.4826 * _median_sorted(mad) / math.sqrt(6)
        floor = 1e-3 * (float(cs[-1]) - baseline) or 1.0
        on, off = baseline + max(6 * noise, floor), baseline + max(3 * noise, 0.25 * floor)
        # the one contact: first sample above on, back to the first above off, release at the next at/below off
        above = np.flatnonzero(c_p > on)
        i_on = int(above[0])
        low = c_p <= off
        i0 = int(np.flatnonzero(low[:i_on])[-1]) + 1
        release = i_on + int(np.argmax(low[i_on:]))
        assert valid[i0 - 1:release + 1].all()
        peak = i0 + min(int(np.argmin(h[i0:release])), int(np.argmax(c_p[i0:release])))
        # first-contact height: root of the 3/2-power law's line (numpy's polyfit arithmetic, one lstsq)
        ex = c_p[i0:peak + 1] - baseline
        y = np.clip(ex, 0.0, None) ** (2.0 / 3.0)
        window = np.flatnonzero((ex >= on - baseline) & (ex <= 0.5 * ex.max()))
        if len(window) < 4:
            window = np.arange(min(4, len(ex)))
        hp = h[i0:peak + 1]
        x = hp[window]
        h_free, h_lo = float(h[i0 - 1]), float(h[i0])
        h_hi = float(np.max(h[:i0][valid[:i0]], initial=h_free))
        assert h_hi > h_lo and len(x) >= 2
        h0 = 0.5 * (h_free + h_lo) if h_free > h_lo else h_lo
        lhs = np.stack([x, np.ones_like(x)], axis=1)
        scale = np.sqrt((lhs * lhs).sum(axis=0))
        lhs /= scale
        slope, icpt = np.linalg.lstsq(lhs, y[window], len(x) * 2.220446049250313e-16)[0] / scale
        if slope < 0:
            h0 = min(max(-icpt / slope, h_lo), h_hi)
        above_h0 = np.flatnonzero(h[:i0] >= h0)
        j = int(above_h0[-1]) if len(above_h0) else i0 - 1
        hj, hk = float(h[j]), float(h[j + 1])
        frac = 0.0 if hj == hk else min(max((hj - h0) / (hj - hk), 0.0), 1.0)
        t_onset = float(t[j]) + frac * (float(t[j + 1]) - float(t[j]))
        depth = float(np.max(h0 - hp))
        c_d = h0 - hp
        np.clip(c_d, 0.0, None, out=c_d)
        x_c = float(xyz[i0:peak + 1, 0].sum()) / (peak + 1 - i0)
        y_c = float(xyz[i0:peak + 1, 1].sum()) / (peak + 1 - i0)
        # the two 3/2-power fits (fit_power_law's arithmetic: estimates, residual sums, standard errors)
        cp = c_p[i0:peak + 1]
        m = len(cp)
        y_mean = float(cp.sum()) / m
        yc = cp - y_mean
        k = []
        for xx in (c_d * 1e3, c_a[i0:peak + 1] * 1e6):
            u = xx**1.5
            u_mean = float(u.sum()) / m
            du = u - u_mean
            sc = math.sqrt(float((du * du).sum()) / m)
            z = du / sc
            szz = float(z @ z)
            b1 = float(z @ yc) / szz
            k1 = b1 / sc
            k += [k1, y_mean - k1 * u_mean]
            resid = yc - b1 * z
            s2 = float(resid @ resid) / (m - 2)
            var_k1 = s2 / (szz * sc**2)
            k += [math.sqrt(var_k1), math.sqrt(s2 / m + u_mean**2 * var_k1)]
        # posterior of both Gaussians and the prior, normalised in log space
        params = np.array([k[0], k[1], k[4], k[5]])
        ll = None
        for j, (mu, li) in enumerate(zip(self.means, self.chol_inv, strict=True)):
            d = params[2 * j:2 * j + 2] - mu
            zz = np.einsum("mij,mj->mi", li, d)
            lp = -0.5 * ((zz * zz).sum(axis=-1) + self.log_det[j] + self.log_2pi)
            ll = lp if ll is None else ll + lp
        joint = ll + self.log_prior
        top = joint.max()
        rest = np.exp(joint - top)
        rest[joint == top] = 0.0
        post = np.exp(joint - (np.log1p(rest.sum() / np.count_nonzero(joint == top))
                                + math.log(np.count_nonzero(joint == top)) + top))
        self.results = (t_onset, depth, k)
        # the map cell under the press: recursive update, clamped in log space
        ix = min(max(math.floor((x_c - self.origin[0]) / self.cell), 0), self.p.shape[1] - 1)
        iy = min(max(math.floor((y_c - self.origin[1]) / self.cell), 0), self.p.shape[0] - 1)
        lp = np.log(self.p[iy, ix]) + np.log(post)
        lp -= lp.max()
        lp -= np.log(np.exp(lp).sum())
        np.maximum(lp, self.log_p_min, out=lp)
        cell = np.exp(lp)
        cell /= cell.sum()
        self.p[iy, ix] = cell
        return post


def stages(recs: list, memory: HapticMemory, new_grid, repeats: int) -> None:
    """Median CPU time per press of each stage of the palpate path, and shifting a press onto the run's timeline."""
    results = [perceive_press(r) for r in recs]
    presses = [r.press for r in results]
    fits = [r.fit for r in results]
    grid = new_grid()
    voxels = VoxelGrid(list(MATERIALS), (32, 32, 6), origin=(-0.04, -0.04), cell_size=0.0025)
    layers = LayeredMemory.whole_press(memory, voxels.cell_size, voxels.shape[2])
    log = PressLog()
    rows = {
        "sync + features + segmentation": (presses_from_recording, recs),
        "two 3/2-power fits (N and A)": (fit_press, presses),
        "haptic-memory posterior": (lambda f: memory.predict_proba(f.params[None, :]), fits),
        "posterior + one 2-D cell (apply_press)": (lambda r: apply_press(grid, r, memory, None, r.location), results),
        "layer fits + voxel column (apply_press)": (
            lambda r: apply_press(voxels, r, memory, layers, r.location), results),
        "PressLog.add (onto the timeline)": (lambda r: log.add(r, {}), recs),
        "  the same by rebuilding each sample": (
            lambda r: ([replace(f, t=f.t + 1.0) for f in r.frames], [replace(p, t=p.t + 1.0) for p in r.poses]),
            recs),
    }
    clock = time.process_time_ns
    print(f"\nPer stage (palpate), median of {repeats} passes, CPU time")
    print(f"{'stage':<40}{'us per press':>14}")
    for name, (fn, items) in rows.items():
        ts = []
        for _ in range(repeats):
            t0 = clock()
            for it in items:
                fn(it)
            ts.append((clock() - t0) / len(items))
        print(f"{name:<40}{statistics.median(ts) / 1e3:14.1f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer presses and repetitions")
    ap.add_argument("--repeats", type=int, default=None, help="passes over all presses")
    args = ap.parse_args()
    n_per, repeats = (4, 20) if args.quick else (10, 60)
    repeats = args.repeats or repeats
    train = recordings(0, 10)
    train_res = [perceive_press(r) for _, r in train]
    memory = HapticMemory(materials=list(MATERIALS)).fit(np.vstack([r.fit.params for r in train_res]),
                                                         [name for name, _ in train])
    recs = [r for _, r in recordings(100, n_per)]
    shape = (8, 8)

    def new_grid() -> Grid2D:
        return Grid2D(list(MATERIALS), shape, origin=(-0.04, -0.04), cell_size=0.01)

    grid = new_grid()
    ref = Reference(memory, new_grid())
    np.seterr(divide="ignore")
    for rec in recs:  # same numbers first: the reference must be the library's arithmetic
        res = perceive_press(rec)
        post = apply_press(grid, res, memory, None, res.location)
        post_ref = ref.press(rec.frames, rec.poses)
        if not (np.array_equal(post, post_ref) and np.array_equal(grid.probabilities, ref.p)):
            raise SystemExit(f"reference and library differ: {post} vs {post_ref}")

    clock = time.process_time_ns
    lib_t, ref_t = [], []
    np.seterr(divide="ignore")  # the reference takes log(0) of an underflowed posterior without a warning
    for k in range(repeats):
        for rec in recs:
            if k % 2:  # who goes first alternates: the second finds the press's samples in the cache
                t0 = clock()
                ref.press(rec.frames, rec.poses)
                t1 = clock()
                res = perceive_press(rec)
                apply_press(grid, res, memory, None, res.location)
                t2 = clock()
                ref_t.append(t1 - t0)
                lib_t.append(t2 - t1)
            else:
                t0 = clock()
                res = perceive_press(rec)
                apply_press(grid, res, memory, None, res.location)
                t1 = clock()
                ref.press(rec.frames, rec.poses)
                t2 = clock()
                lib_t.append(t1 - t0)
                ref_t.append(t2 - t1)
    lib, rf = statistics.median(lib_t) / 1e6, statistics.median(ref_t) / 1e6
    n_frames = np.mean([len(r.frames) for r in recs])
    n_poses = np.mean([len(r.poses) for r in recs])
    print(f"Per-press perception: {len(recs)} presses (seeds 100-102; memory from seeds 0-2), {n_frames:.0f} taxel "
          f"frames and {n_poses:.0f} poses on average, {repeats} interleaved passes, CPU time")
    print("sync + features + segmentation + two fits + posterior + one cell update; "
          "reference = same numbers, bit for bit")
    print(f"{'path':<34}{'median ms/press':>16}{'p90 ms/press':>14}")
    for name, ts in (("palpate (perceive_press + apply_press)", lib_t), ("plain numpy reference", ref_t)):
        print(f"{name:<34}{statistics.median(ts) / 1e6:16.3f}{np.percentile(ts, 90) / 1e6:14.3f}")
    ratio = lib / rf
    print(f"ratio palpate / reference: {ratio:.2f}  (target <= {TARGET}: {'met' if ratio <= TARGET else 'NOT met'})")
    stages(recs, memory, new_grid, max(5, repeats // 4))


if __name__ == "__main__":
    main()
