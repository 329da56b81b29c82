"""Gazebo SDF worlds flattened into named triangle meshes in the map frame.

A Gazebo building is a world of included models: ``<include>`` of ``model://NAME`` found on the model path
(``--model-path`` folders, then ``GAZEBO_MODEL_PATH``), models nested in models, links and their collision (or
visual) geometry, each with its own ``<pose>`` (x y z roll pitch yaw, relative to its parent). Geometry is a
mesh (COLLADA ``.dae`` with its ``<unit>`` and ``<up_axis>`` honoured, or any format trimesh reads, scaled by
``<scale>``) or a primitive: box, cylinder, sphere, capsule, ellipsoid, plane. Collision geometry is the default
because it is what a Gazebo ray sensor hits. Every piece is named ``model::...::link::collision``, so the mesh
world's name rules (see :mod:`pimm_env.world.mesh`) classify it by the models' names.

SDF 1.4-1.9 are read; a world saved by Gazebo with a ``<state>`` takes the models' poses from it. URIs are
found as Gazebo finds them (:mod:`gazebo_paths`): a model or mesh not found is left out and counted (with
``strict``, an error); a URI scheme other than ``model://``/``file://``/a path, an include loop, or geometry it
cannot read is an error naming the SDF file and the element.
"""

from __future__ import annotations

import re
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pimm_env.errors import MapFileError, MissingFileError
from pimm_env.importers.gazebo_paths import BUILTIN_MODELS, GazeboPaths, model_file, model_path


@dataclass
class _Context:
    paths: GazeboPaths  # where URIs lead, and what could not be found
    geometry: str
    meshes: dict[str, Any] = field(default_factory=dict)  # name -> trimesh.Trimesh in the map frame
    cache: dict[tuple[Path, tuple[float, float, float]], Any] = field(default_factory=dict)
    left_out: list[str] = field(default_factory=list)
    including: list[Path] = field(default_factory=list)  # the chain of model files being included, outermost first


def read_sdf_world(
    path: Path, model_paths: Sequence[Path] = (), geometry: str = "collision", strict: bool = False
) -> dict[str, Any]:
    """Every collision (or visual) piece of an SDF world or model file, as trimesh meshes keyed by scoped name.

    URIs resolve as Gazebo resolves them (:mod:`gazebo_paths`). A model or mesh that cannot be found is left out with a
    warning naming each and their count, as Gazebo loads the rest; with ``strict`` it stops the import."""
    path = Path(path)
    if geometry not in ("collision", "visual"):
        raise MapFileError(f"geometry: expected 'collision' or 'visual', got {geometry!r}")
    root = _parse(path)
    folders = [path.parent / "models", path.parent.parent / "models", *model_path(model_paths)]
    context = _Context(GazeboPaths([f for f in folders if f.is_dir()], path.parent, strict), geometry)
    world = root.find("world")
    if world is None:
        models = root.findall("model")
        if not models:
            raise MapFileError(f"{path}: expected an SDF <world> or <model>, found neither")
        for model in models:
            _model(model, np.eye(4), "", path, context)
    else:
        states = _state_poses(world, path)
        for model in world.findall("model"):
            name = model.get("name", "model")
            pose = states.get(name)
            _model(model, np.eye(4), "", path, context, pose)
        for include in world.findall("include"):
            _include(include, np.eye(4), "", path, context)
    if context.left_out:
        warnings.warn(f"{path}: left out {', '.join(context.left_out)}", stacklevel=2)
    missing, case_fixed = context.paths.missing, context.paths.case_fixed
    if missing:
        warnings.warn(
            f"{path}: {len(missing)} model(s) or mesh(es) not found, left out (--strict stops instead): "
            + "; ".join(missing),
            stacklevel=2,
        )
    if case_fixed:
        warnings.warn(f"{path}: found by a name differing in case: {'; '.join(case_fixed)}", stacklevel=2)
    if not context.meshes:
        raise MapFileError(f"{path}: no {geometry} geometry found in the world")
    return context.meshes


def _parse(path: Path) -> ET.Element:
    if not path.is_file():
        raise MissingFileError(f"SDF file {path} does not exist")
    try:
        return ET.parse(path).getroot()
    except ET.ParseError as error:
        raise MapFileError(f"{path}: not valid XML: {error}") from None


def _state_poses(world: ET.Element, path: Path) -> dict[str, np.ndarray]:
    """Model poses of a saved world's ``<state>`` (they replace the models' own)."""
    poses = {}
    for state in world.findall("state"):
        for model in state.findall("model"):
            pose = model.find("pose")
            if pose is not None:
                poses[model.get("name", "")] = pose_matrix(pose, path)
    return poses


def pose_matrix(element: ET.Element | None, path: Path) -> np.ndarray:
    """The 4x4 transform of an SDF ``<pose>`` (x y z roll pitch yaw; fixed axes, yaw applied last)."""
    if element is None or not (element.text or "").strip():
        return np.eye(4)
    frame = element.get("relative_to") or element.get("frame") or ""
    if frame:
        raise MapFileError(f"{path}: <pose relative_to={frame!r}>: poses relative to a named frame are not read")
    values = _floats(element, path, "pose")
    if len(values) != 6:
        raise MapFileError(f"{path}: <pose>: expected x y z roll pitch yaw, got {element.text!r}")
    x, y, z, roll, pitch, yaw = values
    cr, sr, cp, sp, cy, sy = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    matrix = np.eye(4)
    matrix[:3, :3] = np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )
    matrix[:3, 3] = (x, y, z)
    return matrix


def _floats(element: ET.Element, path: Path, what: str) -> list[float]:
    try:
        return [float(v) for v in (element.text or "").split()]
    except ValueError:
        raise MapFileError(f"{path}: <{what}>: expected numbers, got {element.text!r}") from None


def _model(
    model: ET.Element,
    parent: np.ndarray,
    prefix: str,
    path: Path,
    context: _Context,
    pose: np.ndarray | None = None,
) -> None:
    name = f"{prefix}{model.get('name', 'model')}"
    frame = parent @ (pose if pose is not None else pose_matrix(model.find("pose"), path))
    for link in model.findall("link"):
        link_frame = frame @ pose_matrix(link.find("pose"), path)
        for piece in link.findall(context.geometry):
            piece_frame = link_frame @ pose_matrix(piece.find("pose"), path)
            scoped = f"{name}::{link.get('name', 'link')}::{piece.get('name', context.geometry)}"
            mesh = _geometry(piece.find("geometry"), piece_frame, scoped, path, context)
            if mesh is not None:
                context.meshes[_unique(scoped, context.meshes)] = mesh
    for nested in model.findall("model"):
        _model(nested, frame, f"{name}::", path, context)
    for include in model.findall("include"):
        _include(include, frame, f"{name}::", path, context)


def _unique(name: str, taken: dict[str, Any]) -> str:
    candidate, k = name, 1
    while candidate in taken:
        k += 1
        candidate = f"{name}_{k}"
    return candidate


def _include(include: ET.Element, parent: np.ndarray, prefix: str, path: Path, context: _Context) -> None:
    uri_element = include.find("uri")
    uri = (uri_element.text or "").strip() if uri_element is not None else ""
    if not uri:
        raise MapFileError(f"{path}: <include> without a <uri>")
    builtin = uri.removeprefix("model://").strip("/")
    folder = context.paths.resolve(uri, path, "<include>")
    if folder is None:
        if BUILTIN_MODELS.get(builtin):
            context.left_out.append(f"{uri} ({BUILTIN_MODELS[builtin]})")
        return
    sdf_file = model_file(folder) if folder.is_dir() else folder
    root = _parse(sdf_file)
    models = root.findall("model")
    if not models:
        raise MapFileError(f"{sdf_file}: expected a <model> (included by {path})")
    model = models[0]
    name_element = include.find("name")
    new_name = (name_element.text or "").strip() if name_element is not None else ""
    if new_name:
        model.set("name", new_name)
    pose_element = include.find("pose")
    pose = pose_matrix(pose_element, path) if pose_element is not None else None
    here = Path(sdf_file).resolve()
    if here in context.including:  # a model that includes itself, directly or round a loop
        chain = " -> ".join(str(p) for p in [*context.including[context.including.index(here) :], here])
        raise MapFileError(f"{path}: <include> {uri} is a loop of includes ({chain})")
    context.including.append(here)
    try:
        _model(model, parent, prefix, sdf_file, context, pose)
    finally:
        context.including.pop()


def _geometry(geometry: ET.Element | None, frame: np.ndarray, name: str, path: Path, context: _Context) -> Any:
    import trimesh

    if geometry is None or not len(geometry):
        return None
    shape = geometry[0]
    kind = shape.tag
    where = f"{path}: {name}: <{kind}>"
    if kind == "mesh":
        found = _mesh_file(shape, path, name, context)
        if found is None:
            return None
        mesh = found.copy()
    elif kind == "box":
        mesh = trimesh.creation.box(extents=_vector(shape, "size", 3, where))
    elif kind == "cylinder":
        mesh = trimesh.creation.cylinder(
            radius=_scalar(shape, "radius", where), height=_scalar(shape, "length", where), sections=32
        )
    elif kind == "sphere":
        mesh = trimesh.creation.icosphere(subdivisions=2, radius=_scalar(shape, "radius", where))
    elif kind == "capsule":
        mesh = trimesh.creation.capsule(height=_scalar(shape, "length", where), radius=_scalar(shape, "radius", where))
    elif kind == "ellipsoid":
        mesh = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
        mesh.apply_scale(_vector(shape, "radii", 3, where))
    elif kind == "plane":
        mesh = _plane(shape, where)
    elif kind == "empty":
        return None
    else:
        raise MapFileError(
            f"{where}: geometry of this kind is not read (box, cylinder, sphere, capsule, ellipsoid, plane, mesh are)"
        )
    mesh.apply_transform(frame)
    return mesh


def _scalar(shape: ET.Element, tag: str, where: str) -> float:
    return _vector(shape, tag, 1, where)[0]


def _vector(shape: ET.Element, tag: str, n: int, where: str) -> np.ndarray:
    element = shape.find(tag)
    if element is None:
        raise MapFileError(f"{where}: missing <{tag}>")
    try:
        values = np.array([float(v) for v in (element.text or "").split()])
    except ValueError:
        raise MapFileError(f"{where}: <{tag}>: expected numbers, got {element.text!r}") from None
    if len(values) != n or not np.all(np.isfinite(values)) or np.any(values <= 0):
        raise MapFileError(f"{where}: <{tag}>: expected {n} positive number(s), got {element.text!r}")
    return values


def _plane(shape: ET.Element, where: str) -> Any:
    """A plane of the given size (two triangles) whose normal is <normal>."""
    import trimesh

    size = _vector(shape, "size", 2, where)
    normal_element = shape.find("normal")
    normal = np.array([0.0, 0.0, 1.0])
    if normal_element is not None:
        normal = np.array([float(v) for v in (normal_element.text or "0 0 1").split()])
    hx, hy = size / 2
    mesh = trimesh.Trimesh(
        vertices=[[-hx, -hy, 0], [hx, -hy, 0], [hx, hy, 0], [-hx, hy, 0]], faces=[[0, 1, 2], [0, 2, 3]], process=False
    )
    mesh.apply_transform(trimesh.geometry.align_vectors([0, 0, 1], normal / np.linalg.norm(normal)))
    return mesh


def _mesh_file(shape: ET.Element, path: Path, name: str, context: _Context) -> Any:
    uri_element = shape.find("uri")
    uri = (uri_element.text or "").strip() if uri_element is not None else ""
    if not uri:
        raise MapFileError(f"{path}: {name}: <mesh> without a <uri>")
    if shape.find("submesh") is not None:
        raise MapFileError(f"{path}: {name}: <mesh><submesh> is not read; export the submesh as its own file")
    target = context.paths.resolve(uri, path, "<mesh>")
    if target is None:  # not found: left out (said by read_sdf_world)
        return None
    scale_element = shape.find("scale")
    scale = (1.0, 1.0, 1.0)
    if scale_element is not None:
        values = _floats(scale_element, path, "scale")
        if len(values) != 3 or not all(np.isfinite(values)) or min(abs(v) for v in values) == 0:
            raise MapFileError(f"{path}: {name}: <scale>: expected three non-zero numbers, got {scale_element.text!r}")
        scale = (values[0], values[1], values[2])
    key = (target.resolve(), scale)
    if key not in context.cache:
        mesh = read_mesh_file(target)
        mesh.apply_scale(np.array(scale))
        context.cache[key] = mesh
    return context.cache[key]


def read_mesh_file(path: Path) -> Any:
    """One mesh file as one trimesh mesh in metres, z up (COLLADA's <unit> and <up_axis> honoured)."""
    import trimesh

    try:
        scene = trimesh.load(path, force="scene")
    except Exception as error:  # trimesh and its readers raise many kinds for unreadable files
        raise MapFileError(f"{path}: cannot read the mesh: {error}") from None
    if not isinstance(scene, trimesh.Scene):
        raise MapFileError(f"{path}: expected a mesh scene, got {type(scene).__name__}")
    if scene.units not in (None, "meters", "meter", "m"):
        scene = scene.convert_units("meters", guess=False)
    mesh = scene.to_mesh() if len(scene.geometry) else trimesh.Trimesh()
    up = collada_up_axis(path) if path.suffix.lower() == ".dae" else "Z_UP"
    turn = {"Y_UP": [[1, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1]],
            "X_UP": [[0, -1, 0, 0], [0, 0, -1, 0], [1, 0, 0, 0], [0, 0, 0, 1]]}.get(up)  # fmt: skip
    if turn is None or not len(mesh.vertices):
        return mesh
    turned = mesh.copy()
    turned.apply_transform(np.array(turn, dtype=float))
    if turned.extents[2] > ON_END_HEIGHT_M >= mesh.extents[2]:
        # a building tagged Y_UP whose vertices are Z-up, as Gazebo shows it: turned, it would stand tens of metres
        # tall, and as it is it stands a floor high
        warnings.warn(
            f"{path}: tagged {up}, but turned so it would stand {turned.extents[2]:.1f} m tall and "
            f"{min(turned.extents[:2]):.2f} m wide: its vertices are taken as z up",
            stacklevel=2,
        )
        return mesh
    return turned


#: A mesh of one floor that its up-axis tag would stand taller than this (m), while as it is it stands lower, is
#: taken as it is: the tag is wrong (Gazebo shows such files as their vertices stand).
ON_END_HEIGHT_M = 10.0


def collada_up_axis(path: Path) -> str:
    """The ``<up_axis>`` of a COLLADA file's asset (Y_UP when absent, as the format says)."""
    with open(path, "rb") as handle:
        head = handle.read(65536).decode("utf-8", errors="replace")
    found = re.search(r"<up_axis>\s*([XYZ]_UP)\s*</up_axis>", head)
    return found.group(1) if found else "Y_UP"
