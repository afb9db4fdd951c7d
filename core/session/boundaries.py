"""Boundaries in a run: each press's boundary reading (:mod:`palpate.core.boundary`), the reference materials'
moduli from their training presses, and per object a fine material map (:mod:`palpate.core.mapping.fine`) of its
map's plane (a voxel map's surface layer) written beside the map and scored on a 1 mm raster where the truth is
known; its stiffness spots are what reads harder or softer than the plane's material (on a voxel map, a lump
beneath).

Readings need boundary templates made for the scenario's pad; without them (another pad, a finger without one) a
run has no fine map and says why in its summary.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.ndimage import distance_transform_edt

from palpate.core import __version__, limits
from palpate.core.boundary.lump_depth import LumpEvidence, reference_curves, result_curve
from palpate.core.boundary.lump_templates import LUMP_TEMPLATES_FILE, read_lump_templates
from palpate.core.boundary.moduli import MaterialModuli, material_moduli
from palpate.core.boundary.press import read_press
from palpate.core.boundary.reading import NoiseModel
from palpate.core.boundary.templates import TEMPLATES_FILE, BoundaryTemplates, Pad, read_templates
from palpate.core.errors import ValidationError
from palpate.core.files import writing
from palpate.core.mapping.anomalies import anomaly_report
from palpate.core.mapping.calibration import calibration_sample, reliability_table
from palpate.core.mapping.fine import FineMap, boundary_error, edges, fine_map
from palpate.core.mapping.geometry import MapGeometry, plane_probabilities
from palpate.core.mapping.lump_layer import LumpLayer, layer_depths, lump_layer, voxels_on_layer
from palpate.core.mapping.regions import MAX_REGIONS, region_report, volume_regions
from palpate.core.perception.streams import SATURATED
from palpate.core.world.haptic_material import HapticMaterialMap
from palpate.core.world.resources import models_dir
from palpate.core.world.scenario import ObjectEntry, Scenario
from palpate.core.world.scene import FingertipSpec, TaxelSensorSpec
from palpate.core.world.workspace import contact_radius, ground_truth_cells


def shipped_templates() -> BoundaryTemplates:
    """The shipped boundary templates (models/boundary_templates.json), validated."""
    return read_templates(models_dir() / TEMPLATES_FILE)


def noise_of(spec: TaxelSensorSpec, **kw) -> NoiseModel:
    """The reading's sensor model for raw counts of a taxel array described by ``spec``: its noise and rounding
    together, its floor and its 8-bit ceiling (``kw``: NoiseModel's model_error)."""
    return NoiseModel(math.hypot(spec.noise_std, math.sqrt(1 / 12)), float(spec.threshold), float(SATURATED), **kw)


def pad_matches(templates: BoundaryTemplates, tip: FingertipSpec) -> bool:
    """True when ``templates`` were made for ``tip``'s pad."""
    return templates.pad.matches(Pad.of(tip))


def boundary_reader(scenario: Scenario):
    """``(read(recording, result), reason)``: the scenario's per-press boundary reader, or None and why not."""
    try:
        templates = shipped_templates()
    except ValidationError as exc:
        return None, str(exc)
    if not pad_matches(templates, scenario.fingertip):
        return None, ("the shipped boundary templates are for another pad (make templates for this one with "
                      "benchmarks/boundary_templates.py)")
    return functools.partial(_read_or_none, templates=templates, noise=noise_of(scenario.taxels)), None


def lump_evidence(presses: dict[str, tuple] | None, pad: Pad) -> LumpEvidence | None:
    """The shipped lump templates with the reference materials' curves from their training ``presses``
    (PressResults by material) and no press curves yet; None without training presses, or when the templates are
    missing or for another pad than ``pad``."""
    if not presses:
        return None
    try:
        templates = read_lump_templates(models_dir() / LUMP_TEMPLATES_FILE)
    except ValidationError:
        return None
    if not templates.pad.matches(pad):
        return None
    return LumpEvidence(templates, reference_curves(presses, templates.depths), ())


def replay_lump_evidence(presses: dict[str, list]) -> LumpEvidence | None:
    """:func:`lump_evidence` for a replay: the recording's pad is the one the shipped boundary templates read (a
    run reads lumps only where it read boundaries with them)."""
    try:
        pad = shipped_templates().pad
    except ValidationError:
        return None
    return lump_evidence(presses, pad)


def with_curves(evidence: LumpEvidence | None, results) -> LumpEvidence | None:
    """``evidence`` with the press curves of ``results`` (PressResults, one per boundary reading of a map)."""
    if evidence is None:
        return None
    return dataclasses.replace(evidence, curves=tuple(result_curve(r, evidence.templates.depths) for r in results))


#: Points within this distance of a true boundary are "near" it in the calibration summary, m.
NEAR_BOUNDARY = 5e-3

#: Recording metadata key holding the reading's noise model, so that a replay reads every press as the run did.
NOISE_KEY = "boundary_noise"


#: Recording metadata key holding the distance (m) from a map's edge within which a softer press is taken for the
#: object's edge (the contact radius at the planned depth, ``edge_reach`` of
#: :func:`~palpate.core.mapping.anomalies.stiffness_anomalies`), so that a replay finds the run's spots.
EDGE_KEY = "spot_edge_reach_m"


def replay_edge_reach(metadata: dict, where: str) -> float:
    """The edge reach a run recorded (:data:`EDGE_KEY`; 0 for a recording without one: its map's rim cells alone);
    ValidationError naming ``where`` for anything but a finite distance >= 0."""
    value = metadata.get(EDGE_KEY, 0.0)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 <= value < math.inf:
        raise ValidationError(f"{where}: metadata {EDGE_KEY} must be a finite distance >= 0 m, got {value!r}")
    return float(value)


def noise_metadata(scenario: Scenario) -> dict:
    """The run's boundary-reading noise model, as a recording's metadata holds it."""
    n = noise_of(scenario.taxels)
    return {"noise": n.noise, "floor": n.floor, "ceiling": n.ceiling, "model_error": n.model_error}


def replay_reader(metadata: dict, where: str):
    """The reader a run recorded with (its noise model in ``metadata``), or None when the recording has none or
    the templates are missing; ValidationError naming ``where`` for a malformed entry."""
    doc = metadata.get(NOISE_KEY)
    if doc is None:
        return None
    try:
        noise = NoiseModel(float(doc["noise"]), float(doc["floor"]), float(doc["ceiling"]), float(doc["model_error"]))
    except (KeyError, TypeError, ValueError) as exc:
        raise ValidationError(f"{where}: metadata {NOISE_KEY} must hold numbers noise, floor, ceiling and "
                              f"model_error ({exc})") from None
    try:
        templates = shipped_templates()
    except ValidationError:
        return None
    return functools.partial(_read_or_none, templates=templates, noise=noise)


def _read_or_none(recording, result, *, templates: BoundaryTemplates, noise: NoiseModel):
    """:func:`read_press`, or None for a press whose streams the templates cannot read (another pad's sensels: a
    finger without a pad reports its force on a stand-in one)."""
    try:
        return read_press(recording, result, templates, noise)
    except ValidationError:
        return None


def training_moduli(readings: dict[str, tuple]) -> MaterialModuli | None:
    """The reference materials' moduli from their training presses' readings; None when a material has none."""
    try:
        return material_moduli({name: list(rs) for name, rs in readings.items()})
    except ValidationError:
        return None


@dataclass(frozen=True)
class FineResult:
    """An object's fine map, what summary.json says of it, and the truth on its raster (None where unknown)."""

    fine: FineMap
    summary: dict
    truth: np.ndarray | None = None
    lumps: LumpLayer | None = None
    lumps_truth: np.ndarray | None = None


def fine_truth(entry: ObjectEntry, scenario: Scenario, fine: FineMap) -> np.ndarray:
    """The true reference-material index (-1: none) at each fine point, half-way down the planned press."""
    pts = fine.centres()
    z = np.full(pts.shape[0] * pts.shape[1], entry.spec.height - scenario.exploration.depth / 2)
    return ground_truth_cells(entry, scenario, pts.reshape(-1, 2), z).reshape(pts.shape[:2])


def fine_map_findings(fine: FineMap, geometry, probabilities: np.ndarray, readings, moduli: MaterialModuli | None,
                      edge_reach: float = 0.0, lumps: LumpEvidence | None = None) -> dict:
    """What a fine map's summary says it found, for a run and a replay alike: where each material lies at its
    resolution (a buried lump is one region) and the spots that read harder or softer than the cell map
    (``probabilities``, post-processed) names (``edge_reach``, m: see :data:`EDGE_KEY`), with the lump each spot's
    strongest press reads when ``lumps`` holds the readings' press curves."""
    return {"material_regions": region_report(fine.probabilities, fine.origin, fine.resolution, fine.materials,
                                              cell=geometry.cell_size),
            "stiffness_anomalies": anomaly_report(geometry, probabilities, readings, moduli, edge_reach, lumps)}


def plane_fine_map(geometry: MapGeometry, probabilities: np.ndarray, readings, moduli: MaterialModuli | None,
                   edge_reach: float = 0.0, lumps: LumpEvidence | None = None) -> tuple[FineMap, dict]:
    """The fine map of a map's plane (a voxel map's surface layer) from its post-processed ``probabilities`` and
    its presses' ``readings`` ((location, reading) pairs), and its findings (:func:`fine_map_findings`): a run's and
    a replay's alike."""
    plane, cells = geometry.plane(), plane_probabilities(probabilities)
    fine = fine_map(plane, cells, readings, moduli=moduli)
    return fine, fine_map_findings(fine, plane, cells, readings, moduli, edge_reach, lumps)


def voxel_lump_layer(geometry: MapGeometry, fine: FineMap, findings: dict) -> tuple[LumpLayer | None, dict | None]:
    """A voxel map's lump layer (:func:`~palpate.core.mapping.lump_layer.lump_layer`) from its fine map and that
    map's findings, with summary.json's ``lump_layer``: its resolution, depth, the lumps it holds and its largest
    regions (those of a quarter of a cell's footprint or more); (None, None) for a 2-D map or one with no spots;
    (None, {"skipped": why}) for a layer of more cubes than the limit ``map_cells``."""
    spots = findings.get("stiffness_anomalies")
    if not geometry.voxel or spots is None:
        return None, None
    depth = geometry.shape[2] * geometry.cell_size
    cubes = fine.probabilities.shape[0] * fine.probabilities.shape[1] * layer_depths(depth, fine.resolution)
    if cubes > limits.limit("map_cells"):
        return None, {"skipped": f"{cubes} cubes, beyond the limit map_cells ({limits.limit('map_cells'):g}; "
                                 "palpate --limit map_cells=N raises it)"}
    layer = lump_layer(fine, geometry.z_top, depth, geometry.cell_size, spots)
    least = (geometry.cell_size / layer.resolution) ** 2 / 4
    regions = [r for r in volume_regions(layer.probabilities, layer.origin, layer.z_top, layer.resolution,
                                         layer.materials) if r.voxels >= least]
    return layer, {"resolution_m": layer.resolution, "depth_m": layer.probabilities.shape[2] * layer.resolution,
                   "lumps": layer.lumps, "material_regions": [r.to_dict() for r in regions[:MAX_REGIONS]]}


def lump_layer_accuracy(geometry: MapGeometry, probabilities: np.ndarray, layer: LumpLayer,
                        truth: np.ndarray) -> dict:
    """summary.json's share of the layer's cubes each map labels right (``truth``: material index per cube, -1
    unknown): the voxel map (``probabilities`` (nx, ny, nz, M), each cube labelled as the voxel holding its
    centre) and the lump layer, over every known cube (``volume_accuracy``) and over those whose true material is
    not the surface's above them (``below_surface_accuracy``: the lumps; absent where there are none); and the
    layer's expected calibration error (``calibration_ece``) over every known cube (``all``) and over the columns
    a read lump reaches (``under_spots``)."""
    known = truth >= 0
    if not known.any():
        return {}
    voxel = voxels_on_layer(layer, geometry.origin, geometry.cell_size, np.argmax(probabilities, axis=-1))
    labels = np.argmax(layer.probabilities, axis=-1)
    below = known & (truth != truth[:, :, :1])
    out = {}
    for key, mask in (("volume_accuracy", known), ("below_surface_accuracy", below)):
        if mask.any():
            out[key] = {"voxel_map": float(np.mean(voxel[mask] == truth[mask])),
                        "lump_layer": float(np.mean(labels[mask] == truth[mask]))}
    spotted = known & layer.footprint[:, :, None]
    out["calibration_ece"] = masked_ece(layer.probabilities, truth, {"all": known, "under_spots": spotted})
    return out


def save_lump_layer(path: Path, layer: LumpLayer) -> None:
    """``path`` (.npz, no pickled objects): probabilities (nx, ny, nz, M), origin_m, z_top_m, resolution_m,
    materials."""
    with writing(path):
        np.savez_compressed(path, probabilities=layer.probabilities, origin_m=np.asarray(layer.origin),
                            z_top_m=np.asarray(layer.z_top), resolution_m=np.asarray(layer.resolution),
                            materials=np.asarray(layer.materials))


def object_fine_map(obj, entry: ObjectEntry, scenario: Scenario, moduli: MaterialModuli | None,
                    lumps: LumpEvidence | None = None) -> FineResult:
    """The fine map of an explored object's plane from its post-processed map and its presses' readings, with its
    summary: walls read, lumps under its stiffness spots (``lumps``: :func:`lump_evidence`), and with ground truth
    the share of the area each map labels right on the fine raster and how far their boundaries lie from the true
    ones."""
    steps = [s for s in obj.steps if s.boundary is not None]
    readings = [(s.result.location, s.boundary) for s in steps]
    fine, findings = plane_fine_map(obj.geometry, obj.post.probabilities, readings, moduli, contact_radius(scenario),
                                    with_curves(lumps, [s.result for s in steps]))
    summary = {"resolution_m": fine.resolution, "presses_read": len(readings),
               "walls_read": sum(1 for _, r in readings if r.p_boundary > 0.5),
               "sides_named_by": "modulus" if moduli is not None else "neighbour cells"} | findings
    layer, layer_summary = voxel_lump_layer(obj.geometry, fine, findings)
    layer_truth = None
    if layer is not None:
        c = layer.centres()
        layer_truth = ground_truth_cells(entry, scenario, c[..., :2].reshape(-1, 2),
                                         c[..., 2].ravel()).reshape(c.shape[:3])
        layer_summary |= lump_layer_accuracy(obj.geometry, obj.post.probabilities, layer, layer_truth)
    if layer_summary is not None:
        summary["lump_layer"] = layer_summary
    truth = fine_truth(entry, scenario, fine)
    known = truth >= 0
    if not known.any():
        return FineResult(fine, summary, lumps=layer, lumps_truth=layer_truth)
    cells = fine.cells_on_raster(np.argmax(plane_probabilities(obj.post.probabilities), axis=-1))
    labels = fine.labels()
    cell_err, fine_err = (boundary_error(lab, truth, known, fine.resolution) for lab in (cells, labels))
    summary["area_accuracy"] = {"cell_map": float(np.mean(cells[known] == truth[known])),
                                "fine_map": float(np.mean(labels[known] == truth[known]))}
    summary["boundary_error_m"] = {name: {"median": _finite(e[0]), "p90": _finite(e[1])}
                                   for name, e in (("cell_map", cell_err), ("fine_map", fine_err))}
    summary["calibration_ece"] = fine_calibration(fine, truth, known)
    return FineResult(fine, summary, truth, layer, layer_truth)


def near_boundaries(truth: np.ndarray, resolution: float) -> np.ndarray:
    """Points of a material raster (``resolution`` m a point) within NEAR_BOUNDARY of a boundary between two of its
    labels, (ny, nx) bool."""
    return distance_transform_edt(~edges(truth)) * resolution <= NEAR_BOUNDARY


def fine_calibration(fine: FineMap, truth: np.ndarray, mask: np.ndarray) -> dict[str, float]:
    """Expected calibration error of the fine map's most probable material against ``truth`` (material index per
    point) over the points of ``mask``: "all" of them and "near_boundary", those within NEAR_BOUNDARY of a true
    boundary (where the cell map cannot be sure); a key is left out where it has no point."""
    near = near_boundaries(truth, fine.resolution)
    return masked_ece(fine.probabilities, truth, {"all": mask, "near_boundary": mask & near})


def masked_ece(probabilities: np.ndarray, truth: np.ndarray, masks: dict[str, np.ndarray]) -> dict[str, float]:
    """Per named mask, the expected calibration error of ``probabilities`` (points x M) against ``truth`` (material
    index per point) over the mask's points; a mask with no point is left out."""
    return {where: reliability_table(*calibration_sample(probabilities[m], truth[m])[:2]).ece
            for where, m in masks.items() if m.any()}


def _finite(v: float) -> float | None:
    return float(v) if np.isfinite(v) else None


def export_fine_map(folder: Path, fine: FineMap, name: str, scenario: Scenario) -> Path:
    """The fine map in seed 002's haptic-material format at its own resolution (probabilities only; the palpation
    features stay with the cell map's export)."""
    hm = HapticMaterialMap(tuple(fine.origin), float(fine.resolution), list(fine.materials), fine.probabilities,
                           meta={"object": name, "scenario": scenario.name, "palpate": __version__,
                                 "layer": "fine map from the presses' boundary readings"})
    return hm.write(folder)


def save_fine_map(path: Path, fine: FineMap) -> None:
    """``path`` (.npz, no pickled objects): probabilities (ny, nx, M), origin_m, resolution_m, materials."""
    with writing(path):
        np.savez_compressed(path, probabilities=fine.probabilities, origin_m=np.asarray(fine.origin),
                            resolution_m=np.asarray(fine.resolution), materials=np.asarray(fine.materials))
