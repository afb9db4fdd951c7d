"""Realism profile files (TOML, ``models/realism/*.toml``): read, validated, written, and found by name.

A file lists only what departs from ``ideal``; every key carries its unit in its name; an unknown key or a bad value
is an error naming the file and the key (``x.toml: press.tilt_deg: must be <= 29.9, got 45.0``). Example::

    [profile]
    name = "lab"
    description = "a human finger in a lab"

    [finger]
    compliant = true
    stiffness_n_per_mm = 0.5
    stiffening_per_mm = 1.0
    area_factor = 2.0
    stiffness_cv = 0.2
    pressure_exponent = 0.5

    [press]          # speed_cv, depth_cv, lateral_mm, hold_s, smooth, tilt_deg, slip, tremor_mm, force_scale,
                     # push_force_n, push_depth_scale, push_stiffness_n_per_mm, tail_dof
    tilt_deg = 5.0

    [taxels]         # sensitivity, gain_spread, gain_drift, hysteresis, creep, nonlinearity, crosstalk,
                     # activation_kpa, activation_cv
    [pose]           # latency_ms, clock_offset_ms, clock_wander_ms
    [material]       # relaxation, relaxation_time_s, softening, softening_presses, plateau_strain,
                     # plateau_materials (an array of material names), densify_strain
    [provenance]     # free record (strings, numbers, arrays, tables): references, or the calibration's fit

``palpate calibrate realism`` writes such files (:func:`profile_to_toml`).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from palpate.core.errors import ValidationError
from palpate.core.files import read_toml
from palpate.core.world.resources import models_dir
from palpate.core.world.table_reader import TableReader
from palpate.sim.controller import HUMAN, Variability
from palpate.sim.realism.profile import (
    IDEAL,
    PRESETS,
    FingerPulp,
    MaterialRealism,
    PoseRealism,
    RealismProfile,
    TaxelRealism,
)

#: Where shipped profiles live (models/realism, also from a wheel); a scenario may name one by its file stem.
PROFILES_DIR = models_dir() / "realism"


def shipped_profiles() -> list[str]:
    """Names of the profiles shipped in models/realism (file stems)."""
    return sorted(p.stem for p in PROFILES_DIR.glob("*.toml")) if PROFILES_DIR.is_dir() else []


def resolve_profile(spec: str | Path | RealismProfile | None) -> RealismProfile:
    """A profile from a preset name, a shipped profile's name, a path to a TOML file, or a profile (None: ideal).

    Raises:
        ValidationError: an unknown name (naming the known ones) or an invalid file (naming file and key).
    """
    if spec is None:
        return IDEAL
    if isinstance(spec, RealismProfile):
        return spec
    text = str(spec)
    if text in PRESETS:
        return PRESETS[text]
    if isinstance(spec, Path) or text.endswith(".toml") or "/" in text or "\\" in text:
        return load_profile(Path(spec))
    if text in shipped_profiles():
        return load_profile(PROFILES_DIR / f"{text}.toml")
    known = ", ".join([*PRESETS, *shipped_profiles()])
    raise ValidationError(f"unknown realism profile {text!r}; presets and shipped profiles: {known} (or a .toml path)")


def load_profile(path: str | Path) -> RealismProfile:
    """Read and validate a profile file (TOML, bounded by the ``text_mb`` limit). Errors name the file and the key."""
    p = Path(path)
    # read_toml turns every parse failure (bad syntax, an integer past Python's digit limit, nesting too deep) into
    # one line naming the file
    return parse_profile(read_toml(p, "realism profile"), str(p), default_name=p.stem)


def parse_profile(raw: dict, file: str = "<profile>", default_name: str = "profile") -> RealismProfile:
    """Validate a profile given as a parsed TOML dictionary (see :func:`load_profile`)."""
    top = TableReader(file, raw, "")
    head = top.sub("profile")
    name = head.get("name", str, default_name)
    description = head.get("description", str, "")
    head.finish()
    try:
        f = top.sub("finger")
        d = FingerPulp()
        finger = FingerPulp(
            compliant=f.get("compliant", bool, d.compliant),
            stiffness=f.number("stiffness_n_per_mm", d.stiffness * 1e-3, lo=0.0, lo_open=True) * 1e3,
            stiffening=f.number("stiffening_per_mm", d.stiffening * 1e-3, lo=0.0) * 1e3,
            area_factor=f.number("area_factor", d.area_factor, lo=0.0),
            stiffness_cv=f.number("stiffness_cv", d.stiffness_cv, lo=0.0),
            pressure_exponent=f.number("pressure_exponent", d.pressure_exponent, lo=0.5, hi=2.99),
        )
        f.finish()
        pr = top.sub("press")
        press = Variability(
            speed_cv=pr.number("speed_cv", HUMAN.speed_cv, lo=0.0, hi=0.49),
            depth_cv=pr.number("depth_cv", HUMAN.depth_cv, lo=0.0, hi=0.49),
            lateral_std=pr.number("lateral_mm", HUMAN.lateral_std * 1e3, lo=0.0) * 1e-3,
            hold_std=pr.number("hold_s", HUMAN.hold_std, lo=0.0),
            smooth=pr.get("smooth", bool, HUMAN.smooth),
            tilt_std=float(np.deg2rad(pr.number("tilt_deg", 0.0, lo=0.0, hi=29.9))),
            slip_std=pr.number("slip", 0.0, lo=0.0),
            tremor=pr.number("tremor_mm", 0.0, lo=0.0) * 1e-3,
            force_scale=pr.number("force_scale", 1.0, lo=0.01, hi=10.0),
            push_force=pr.number("push_force_n", 0.0, lo=0.0, hi=50.0),
            push_depth_scale=pr.number("push_depth_scale", 2.0, lo=1.0, hi=10.0),
            push_stiffness=pr.number("push_stiffness_n_per_mm", 0.0, lo=0.0, hi=100.0) * 1e3,
            tail_dof=_tail_dof(pr),
        )
        pr.finish()
        tx = top.sub("taxels")
        taxels = TaxelRealism(sensitivity=tx.number("sensitivity", 1.0, lo=0.01, hi=100.0),
                              **{k: tx.number(k, 0.0, lo=0.0) for k in
                                 ("gain_spread", "gain_drift", "hysteresis", "creep", "nonlinearity", "crosstalk")},
                              activation=tx.number("activation_kpa", 0.0, lo=0.0, hi=100.0) * 1e3,
                              activation_cv=tx.number("activation_cv", 0.0, lo=0.0, hi=2.99))
        tx.finish()
        po = top.sub("pose")
        pose = PoseRealism(latency=po.number("latency_ms", 0.0) * 1e-3,
                           clock_offset_std=po.number("clock_offset_ms", 0.0, lo=0.0) * 1e-3,
                           clock_wander=po.number("clock_wander_ms", 0.0, lo=0.0) * 1e-3)
        po.finish()
        ma = top.sub("material")
        dm = MaterialRealism()
        material = MaterialRealism(relaxation=ma.number("relaxation", 0.0, lo=0.0),
                                   relaxation_time=ma.number("relaxation_time_s", dm.relaxation_time, lo=0.0,
                                                             lo_open=True),
                                   softening=ma.number("softening", 0.0, lo=0.0),
                                   softening_presses=ma.number("softening_presses", dm.softening_presses, lo=0.0,
                                                               lo_open=True),
                                   plateau_strain=_plateau_strain(ma),
                                   plateau_materials=_names(ma, "plateau_materials"),
                                   densify_strain=_densify_strain(ma))
        ma.finish()
    except ValidationError as exc:
        msg = str(exc)
        raise ValidationError(msg if msg.startswith(file) else f"{file}: {msg}") from None
    provenance = top.get("provenance", dict, {})
    _check_provenance(provenance, TableReader(file, provenance, "provenance"))
    top.finish()
    return RealismProfile(name, description, finger, press, taxels, pose, material, provenance)


def _tail_dof(pr: TableReader) -> float:
    """``press.tail_dof``: 0 (off) or the careless press's degrees of freedom, 1 (Cauchy) to 1000."""
    dof = pr.number("tail_dof", 0.0, lo=0.0, hi=1000.0)
    if 0.0 < dof < 1.0:
        raise pr.err("tail_dof", f"must be 0 (off) or >= 1 degree of freedom, got {dof}")
    return dof


def _plateau_strain(ma: TableReader) -> float:
    """``material.plateau_strain``: 0 (off) or a strain below 0.5 that some ``plateau_materials`` have."""
    strain = ma.number("plateau_strain", 0.0, lo=0.0, hi=0.49)
    if strain > 0 and not ma.table.get("plateau_materials"):
        raise ma.err("plateau_materials", "plateau_strain > 0 needs the names of the cellular materials that have "
                     "the plateau (a rubber has none)")
    return strain


def _densify_strain(ma: TableReader) -> float:
    """``material.densify_strain``: 0 (off) or a strain above ``plateau_strain``, below 0.6, of the
    ``plateau_materials``."""
    strain = ma.number("densify_strain", 0.0, lo=0.0, hi=0.6)
    if strain > 0 and not ma.table.get("plateau_materials"):
        raise ma.err("plateau_materials", "densify_strain > 0 needs the names of the cellular materials that densify")
    plateau = ma.table.get("plateau_strain", 0.0)
    if 0 < strain <= plateau:
        raise ma.err("densify_strain", f"must exceed plateau_strain ({plateau}): cells touch after they buckle")
    return strain


def _names(table: TableReader, key: str) -> tuple[str, ...]:
    """An array of distinct, non-empty names (``material.plateau_materials``)."""
    names = table.get(key, list, [])
    if not all(isinstance(n, str) and n for n in names):
        raise table.err(key, f"must be an array of material names, got {names!r}")
    if len(set(names)) != len(names):
        raise table.err(key, f"names repeat: {names!r}")
    return tuple(names)


def _check_provenance(value, where: TableReader, depth: int = 0) -> None:
    """Provenance holds only strings, finite numbers, booleans, arrays and tables of them (a record, no code)."""
    if depth > 6:
        raise where.err("", "nested too deeply")
    for key, v in value.items():
        if isinstance(v, dict):
            _check_provenance(v, TableReader(where.file, v, f"{where.path}.{key}"), depth + 1)
        elif isinstance(v, list):
            if not all(isinstance(x, (str, int, float, bool)) and (not isinstance(x, float) or np.isfinite(x))
                       for x in v):
                raise where.err(key, "arrays may hold only strings, finite numbers and booleans")
        elif isinstance(v, float) and not np.isfinite(v):
            raise where.err(key, "must be finite")
        elif not isinstance(v, (str, int, float, bool)):
            raise where.err(key, f"unsupported value {v!r}")


def profile_to_toml(profile: RealismProfile) -> str:
    """The profile as a TOML document that :func:`parse_profile` reads back to an equal profile."""
    lines: list[str] = []
    for name, table in profile_tables(profile).items():
        _emit_table(lines, name, table)
    return "\n".join(lines).rstrip() + "\n"


def profile_tables(profile: RealismProfile) -> dict:
    """The profile as the tables of its file (keys with units), which :func:`parse_profile` reads."""
    f, p, t, o, m = profile.finger, profile.press, profile.taxels, profile.pose, profile.material
    tables = {
        "profile": {"name": profile.name, "description": profile.description},
        "finger": {"compliant": f.compliant, "stiffness_n_per_mm": f.stiffness * 1e-3,
                   "stiffening_per_mm": f.stiffening * 1e-3, "area_factor": f.area_factor,
                   "stiffness_cv": f.stiffness_cv, "pressure_exponent": f.pressure_exponent},
        "press": {"speed_cv": p.speed_cv, "depth_cv": p.depth_cv, "lateral_mm": p.lateral_std * 1e3,
                  "hold_s": p.hold_std, "smooth": p.smooth, "tilt_deg": float(np.rad2deg(p.tilt_std)),
                  "slip": p.slip_std, "tremor_mm": p.tremor * 1e3, "force_scale": p.force_scale,
                  "push_force_n": p.push_force, "push_depth_scale": p.push_depth_scale,
                  "push_stiffness_n_per_mm": p.push_stiffness * 1e-3,
                  "tail_dof": p.tail_dof},
        "taxels": {"sensitivity": t.sensitivity, "gain_spread": t.gain_spread, "gain_drift": t.gain_drift,
                   "hysteresis": t.hysteresis, "creep": t.creep, "nonlinearity": t.nonlinearity,
                   "crosstalk": t.crosstalk, "activation_kpa": t.activation * 1e-3,
                   "activation_cv": t.activation_cv},
        "pose": {"latency_ms": o.latency * 1e3, "clock_offset_ms": o.clock_offset_std * 1e3,
                 "clock_wander_ms": o.clock_wander * 1e3},
        "material": {"relaxation": m.relaxation, "relaxation_time_s": m.relaxation_time, "softening": m.softening,
                     "softening_presses": m.softening_presses, "plateau_strain": m.plateau_strain,
                     "plateau_materials": list(m.plateau_materials), "densify_strain": m.densify_strain},
    }
    if profile.provenance:
        tables["provenance"] = profile.provenance
    return tables


def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        if not np.isfinite(v):
            raise ValidationError(f"profile_to_toml: non-finite value {v!r}")
        return repr(float(v))
    if isinstance(v, str):
        return json.dumps(v)  # a JSON string is a valid TOML basic string
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    raise ValidationError(f"profile_to_toml: cannot write {type(v).__name__} {v!r}")


def _emit_table(lines: list[str], name: str, table: dict) -> None:
    lines.append(f"[{name}]")
    subs = []
    for key, v in table.items():
        if isinstance(v, dict):
            subs.append((key, v))
        else:
            lines.append(f"{_key(key)} = {_value(v)}")
    lines.append("")
    for key, v in subs:
        _emit_table(lines, f"{name}.{_key(key)}", v)


def _key(key: str) -> str:
    return key if key.replace("_", "").replace("-", "").isalnum() else json.dumps(key)
