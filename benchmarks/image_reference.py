"""The 3-D FE image reference (models/image_reference.json): computes the cases of sim/validity/image_cases.py,
prints each case's image summary, the mesh convergence of the image (rms change under h -> h / sqrt(2) as a share
of the finer image's peak sensel pressure, and the force change), the checks of the model (the full model against
the half model and the axisymmetric FE on a plain block at nu 0.45 and 0.49, wider sides) and the sanity figures.

Run: .venv/bin/python benchmarks/image_reference.py [--quick | --core] [--write] [--only SUBSTRING] [--no-checks]
  --quick: the plain block and the 20|115 kPa wall on the axis, the block's convergence only (~2 min);
  --core: the core subset (plain block nu 0.45, the 20|115 kPa wall at t = 0, nu 0.45, offsets -4..6 mm);
  --write: merge the computed cases (and convergence) into the file, written after each case.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from palpate.core.world.scene import FingertipSpec, Material, TaxelSensorSpec
from palpate.sim.reference.fe import fe_press
from palpate.sim.reference.fe3d import BoxBlock, Wall
from palpate.sim.reference.fe3d_image import fe3d_image, radial_image
from palpate.sim.reference.sample import AxisymmetricSample
from palpate.sim.validity.image import PressImage, active_sensels, asymmetry, image_errors
from palpate.sim.validity.image_cases import HALF, THICKNESS, core_cases, image_cases, wall_case
from palpate.sim.validity.image_reference import (
    DEFAULT_MESH,
    FORMAT,
    GROWTH,
    IMAGE_REFERENCE_PATH,
    NEAR_INCOMPRESSIBLE,
    VERSION,
    H,
    compute_case,
    convergence_study,
    load_image_reference,
    new_document,
)

TIP = FingertipSpec()
TAXELS = TaxelSensorSpec()
CONVERGENCE = ("block_115kPa_nu0.45", "wall_20-115kPa_t0_o+0mm_nu0.45", "wall_20-115kPa_t0_o+2mm_nu0.45",
               "wall_20-115kPa_t45_o+0mm_nu0.45", "lump_2000-115kPa_near0mm", "skin_20-200kPa_0.5mm",
               "block_115kPa_nu0.49")


def _image(entry: dict) -> PressImage:
    return PressImage(depth=np.array(entry["depth"]), force=np.array(entry["force"]),
                      pressure=np.array(entry["pressure"]))


def _summary(name: str, image: PressImage, extra: str = "") -> None:
    p = image.pressure[-1] / 1e3
    print(f"{name:<40} F {' '.join(f'{f:6.3f}' for f in image.force)} N | 4 mm: centre {p[1:3, 1:3].mean():5.1f} "
          f"corner {p[[0, 0, 3, 3], [0, 3, 0, 3]].mean():5.1f} kPa | asym x "
          f"{' '.join(f'{a:+.2f}' for a in asymmetry(image.pressure))}, y at 4 mm "
          f"{float(asymmetry(image.pressure[-1], 'y')):+.2f} | active "
          f"{' '.join(str(int(a)) for a in active_sensels(image.pressure, TAXELS))} {extra}", flush=True)


def _write(path: Path, doc: dict) -> None:
    path.write_text(json.dumps(doc, separators=(",", ":")) + "\n")


def _load_or_new(path: Path) -> dict:
    if path.exists():
        doc = json.loads(path.read_text())
        if doc.get("format") == FORMAT and doc.get("version") == VERSION and doc.get("mesh", {}).get("h") == H:
            return doc
    return new_document(TIP)


def print_convergence(name: str, study: dict) -> None:
    levels = [_image(lev) for lev in study["levels"]]
    for lev, image in zip(study["levels"][:-1], levels[:-1], strict=True):
        err = image_errors(image, levels[-1], TIP)
        print(f"  {name:<38} h {1e3 * lev['h']:.3f} -> {1e3 * study['levels'][-1]['h']:.3f} mm "
              f"({lev['dofs']} -> {study['levels'][-1]['dofs']} dofs): image rms change % of peak "
              f"{' '.join(f'{100 * v:4.1f}' for v in err.rms_share)}; force change % "
              f"{' '.join(f'{100 * v:+5.2f}' for v in err.force_error)}", flush=True)


def checks() -> None:
    """The full model against the half model and the axisymmetric FE on the plain block; wider sides."""
    m = Material("115kPa", 115e3, 0.45)
    block = BoxBlock(m, THICKNESS, HALF, HALF)
    depths = np.array([0.5, 1, 2, 3, 4]) * 1e-3
    t0 = time.perf_counter()
    half, _ = fe3d_image(block, TIP, depths, h=H, growth=GROWTH)
    t1 = time.perf_counter()
    full, field = fe3d_image(block, TIP, depths, h=H, growth=GROWTH, half=False)
    t2 = time.perf_counter()
    err = image_errors(full, half, TIP)
    print(f"full ({field.dofs} dofs, {t2 - t1:.0f} s) vs half model ({t1 - t0:.0f} s): force % "
          f"{' '.join(f'{100 * v:+.3f}' for v in err.force_error)}; image rms % of peak "
          f"{' '.join(f'{100 * v:.3f}' for v in err.rms_share)}")
    axi = fe_press(AxisymmetricSample(m, THICKNESS), TIP.radius, depths, refinement=1.0)
    err = image_errors(full, radial_image(axi.depth, axi.force, axi.r, axi.pressure, TIP), TIP)
    print(f"full model vs axisymmetric FE (refinement 1): force % "
          f"{' '.join(f'{100 * v:+.2f}' for v in err.force_error)}; image rms % of peak "
          f"{' '.join(f'{100 * v:.2f}' for v in err.rms_share)}")
    # near incompressibility: the default mesh against the one the nu >= 0.48 cases use
    m49 = Material("115kPa", 115e3, 0.49)
    axi = fe_press(AxisymmetricSample(m49, THICKNESS), TIP.radius, depths, refinement=1.0)
    axi_image = radial_image(axi.depth, axi.force, axi.r, axi.pressure, TIP)
    for label, mesh in (("default mesh", DEFAULT_MESH), ("near-incompressible mesh", NEAR_INCOMPRESSIBLE)):
        img, field = fe3d_image(BoxBlock(m49, THICKNESS, HALF, HALF), TIP, depths, **mesh)
        err = image_errors(img, axi_image, TIP)
        print(f"nu 0.49 plain block, {label} ({field.dofs} dofs) vs axisymmetric FE: force % "
              f"{' '.join(f'{100 * v:+.2f}' for v in err.force_error)}; image rms % of peak "
              f"{' '.join(f'{100 * v:.2f}' for v in err.rms_share)}", flush=True)
    wide, _ = fe3d_image(BoxBlock(m, THICKNESS, 1.5 * HALF, 1.5 * HALF), TIP, depths, h=H, growth=GROWTH)
    err = image_errors(half, wide, TIP)
    print(f"sides at {1e3 * HALF:g} mm vs {1.5e3 * HALF:g} mm: force % "
          f"{' '.join(f'{100 * v:+.2f}' for v in err.force_error)}; image rms % of peak "
          f"{' '.join(f'{100 * v:.2f}' for v in err.rms_share)}")
    # the volume-fraction mixing of a rotated wall, measured where the exact answer is known: a wall along y
    # 0.35 mm off (mid-cell at h 0.7 mm) turned by 1e-6 rad, so it is mixed, against the same wall on a grid line
    exact = wall_case(20, 115, 0.45, 0, 0.35)
    aligned, _ = fe3d_image(exact.block, TIP, depths, h=H, growth=GROWTH)
    for factor in (1.0, 2**-0.5):
        mixed_block = BoxBlock(exact.block.material, THICKNESS, HALF, HALF,
                               wall=Wall(exact.block.wall.material, 1e-6, 0.35e-3))
        mixed, field = fe3d_image(mixed_block, TIP, depths, h=H * factor, growth=GROWTH)
        err = image_errors(mixed, aligned, TIP)
        print(f"wall 20|115 +0.35 mm mixed by volume fraction (h {1e3 * H * factor:.3f} mm, {field.dofs} dofs) vs "
              f"on a grid line (h {1e3 * H:g}): force % {' '.join(f'{100 * v:+.2f}' for v in err.force_error)}; "
              f"image rms % {' '.join(f'{100 * v:.2f}' for v in err.rms_share)}; asym x "
              f"{' '.join(f'{v:+.3f}' for v in err.asymmetry)} vs "
              f"{' '.join(f'{v:+.3f}' for v in err.reference_asymmetry)}",
              flush=True)
    for angle in (0.0, 90.0):
        case = wall_case(20, 115, 0.45, angle, 2)
        img, field = fe3d_image(case.block, TIP, depths, h=H, growth=GROWTH, half=False)
        if angle == 0.0:
            ref_img = img
        else:
            # the 90 deg wall is the 0 deg one turned a quarter: the pad's columns become its rows
            turned = np.rot90(ref_img.pressure, k=1, axes=(1, 2))
            rms = np.sqrt(np.mean((img.pressure - turned) ** 2, axis=(1, 2))) / turned.max(axis=(1, 2))
            print(f"wall 20|115 +2 mm at 90 deg (full model) vs at 0 deg turned: force % "
                  f"{' '.join(f'{100 * v:+.3f}' for v in img.force / ref_img.force - 1)}; image rms % "
                  f"{' '.join(f'{100 * v:.3f}' for v in rms)}")


def sanity(doc: dict) -> None:
    cases = doc["cases"]
    block = cases.get("block_115kPa_nu0.45")
    if block:
        img = _image(block)
        p = img.pressure[-1] / 1e3
        print(f"plain block 115 kPa nu 0.45, 4 mm: centre sensels {p[1:3, 1:3].mean():.1f} kPa, corners "
              f"{p[[0, 0, 3, 3], [0, 3, 0, 3]].mean():.1f} kPa; active at 1 / 2 mm "
              f"{int(active_sensels(img.pressure[1], TAXELS))} / {int(active_sensels(img.pressure[2], TAXELS))}")
    for offset in (-6, -4, -2, -1, 0, 1, 2, 4, 6):
        entry = cases.get(wall_case(20, 115, 0.45, 0, offset).name)
        if entry:
            img = _image(entry)
            print(f"wall 20|115 kPa, t 0, offset {offset:+d} mm, 4 mm deep: x-asymmetry "
                  f"{float(asymmetry(img.pressure[-1])):+.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--core", action="store_true")
    parser.add_argument("--write", action="store_true")
    parser.add_argument("--only", default="")
    parser.add_argument("--no-checks", action="store_true")
    parser.add_argument("--no-convergence", action="store_true")
    args = parser.parse_args()
    if args.quick:
        cases = [c for c in image_cases() if c.name in ("block_115kPa_nu0.45", "wall_20-115kPa_t0_o+0mm_nu0.45")]
        study = ("block_115kPa_nu0.45",)
    else:
        cases = core_cases() if args.core else image_cases()
        study = CONVERGENCE
    cases = [c for c in cases if args.only in c.name]
    doc = _load_or_new(IMAGE_REFERENCE_PATH) if args.write else new_document(TIP)
    print(f"3-D FE images: h {1e3 * H:g} mm across the contact, growth {GROWTH:g} (nu >= 0.48: {NEAR_INCOMPRESSIBLE}); "
          f"{len(cases)} cases")
    for case in cases:
        entry = compute_case(case, TIP)
        doc["cases"][case.name] = entry
        _summary(case.name, _image(entry), f"({entry['dofs']} dofs, {entry['seconds']:.0f} s)")
        if args.write:
            _write(IMAGE_REFERENCE_PATH, doc)
    if not args.no_convergence:
        print("\nMesh convergence (each level against the finest):")
        for case in cases:
            if case.name in study:
                doc["convergence"][case.name] = convergence_study(case, TIP)
                print_convergence(case.name, doc["convergence"][case.name])
                if args.write:
                    _write(IMAGE_REFERENCE_PATH, doc)
    print("\nSanity:")
    sanity(doc)
    if not args.no_checks and not args.quick:
        print("\nChecks:")
        checks()
    if args.write:
        load_image_reference(IMAGE_REFERENCE_PATH)
        print(f"\nwrote {IMAGE_REFERENCE_PATH} ({len(doc['cases'])} cases)")


if __name__ == "__main__":
    main()
