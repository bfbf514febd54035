"""The object library and object specification files.

``load_object(name_or_path)`` is the one way every pushbot tool turns an object argument into an
:class:`ObjectSpec`: a library name (the MIT pushing dataset objects bundled in
``push_core/data/mit_push_objects.json``) or a path to a JSON/YAML object specification file
(format in ``docs/design/objects.md``).

Frames and units: SI. Every shape is re-centred on its area centroid, which becomes the object
frame origin; ``ObjectSpec.com`` is the centre of mass in that frame (zero for uniform density).
The COM must lie inside the convex hull of the outline (not necessarily inside the outline: the
centroid of an L or U shape lies outside its footprint).
``ObjectSpec.source_origin`` records where the source file's own origin lies in the object frame,
so poses given in the source's frame can be converted.

Data source: Yu, Bauza, Fazeli, Rodriguez, "More than a million ways to be pushed. A
high-fidelity experimental dataset of planar pushing", IROS 2016 (the MIT pushing dataset),
as condensed in ``shared/objects/mit_push_objects.json``; copied unchanged.
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial import ConvexHull

from push_core.shapes import Ellipse, Polygon, Shape

__all__ = [
    "DEFAULT_FRICTION_PUSHER",
    "DEFAULT_FRICTION_TABLE",
    "TEST_OBJECTS",
    "ObjectSpec",
    "library_names",
    "limit_surface_guess",
    "load_object",
    "object_from_dict",
]

#: Objects the source held out of all training (thesis chapter 5).
TEST_OBJECTS = ("tri1", "butter", "hex")
#: Coulomb coefficients used when a spec does not give them (steel on steel / on a hard table).
DEFAULT_FRICTION_TABLE = 0.25
DEFAULT_FRICTION_PUSHER = 0.25

_LIBRARY_FILE = "mit_push_objects.json"
_SPEC_SUFFIXES = (".json", ".yaml", ".yml")


@dataclass(frozen=True, eq=False)
class ObjectSpec:
    """A flat, extruded object with its physical parameters.

    Attributes
    ----------
    name : str
    shape : Polygon | Ellipse
        Outline in the object frame (area centroid at the origin), metres.
    thickness : float
        Extrusion height, metres.
    mass : float
        kg.
    com : (2,) ndarray
        Centre of mass in the object frame, metres; inside the convex hull of ``shape``.
    friction_table, friction_pusher : float
        Coulomb coefficients object-table and pusher-object.
    source : str
        ``"library:<name>"`` or the spec file's path.
    source_origin : (2,) ndarray
        The source description's origin expressed in the object frame.

    Equality is identity (the fields hold arrays); compare fields explicitly.
    """

    name: str
    shape: Shape
    thickness: float
    mass: float
    com: np.ndarray
    friction_table: float = DEFAULT_FRICTION_TABLE
    friction_pusher: float = DEFAULT_FRICTION_PUSHER
    source: str = ""
    source_origin: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(2))

    def __post_init__(self) -> None:
        _positive("thickness", self.thickness)
        _positive("mass", self.mass)
        _non_negative("friction_table", self.friction_table)
        _non_negative("friction_pusher", self.friction_pusher)
        com = _vector2("com_offset", self.com)
        if not _inside_hull(self.shape, com):
            raise ValueError(
                f"com_offset: {com.tolist()} m (object frame) lies outside the convex hull of "
                "the object's outline; a rigid flat body's centre of mass lies inside it"
            )
        com.setflags(write=False)
        object.__setattr__(self, "com", com)
        object.__setattr__(self, "source_origin", _vector2("source_origin", self.source_origin))
        for name in ("thickness", "mass", "friction_table", "friction_pusher"):
            object.__setattr__(self, name, float(getattr(self, name)))

    def replace(self, **changes: Any) -> ObjectSpec:
        """A copy with some fields changed, validated again.

        Example: ``spec.replace(com=(0.01, 0.0), friction_table=0.3)``.
        """
        return dataclasses.replace(self, **changes)

    @property
    def area(self) -> float:
        return self.shape.area

    @property
    def moment_of_inertia(self) -> float:
        """Moment of inertia about the vertical axis through the COM (uniform density), kg m^2."""
        return self.mass / self.shape.area * self.shape.polar_moment(about=self.com)

    def outline(self, spacing: float = 0.002) -> tuple[np.ndarray, np.ndarray]:
        """Outline points and outward unit normals in the object frame, counter-clockwise."""
        return self.shape.outline(spacing)

    def polyline(self) -> np.ndarray:
        """Closed counter-clockwise polyline (P, 2) of the outline for contact queries."""
        return self.shape.polyline()

    def limit_surface_guess(self, n: int = 20000, seed: int = 0) -> float:
        """Limit-surface parameter ``l`` for uniform pressure, metres.

        ``l = tau_max / f_max`` = mean distance of the support area from the COM (for a disc of
        radius R this is 2R/3). Estimated by uniform sampling over the area with a fixed seed.
        """
        return limit_surface_guess(self.shape, self.com, n, seed)


def limit_surface_guess(shape: Shape, com: np.ndarray, n: int = 20000, seed: int = 0) -> float:
    """Limit-surface parameter ``l`` of a shape under uniform pressure, in the shape's unit.

    ``l = tau_max / f_max`` = the mean distance of the support area from the COM ``com`` (2,)
    (shape frame); a disc of radius R gives 2R/3. Uniform sampling of ``n`` points with a fixed
    ``seed`` (:meth:`ObjectSpec.limit_surface_guess` is this function).
    """
    samples = _sample_area(shape, n, np.random.default_rng(seed))
    return float(np.mean(np.linalg.norm(samples - np.asarray(com, dtype=float), axis=1)))


def library_names() -> list[str]:
    """Names of the bundled library objects, in file order."""
    return list(_library()["objects"].keys())


def load_object(name_or_path: str | Path) -> ObjectSpec:
    """Load a library object by name or an object specification file by path.

    Raises
    ------
    ValueError
        Unknown name, unreadable file or invalid specification (the message names the field).
    """
    text = str(name_or_path)
    path = Path(text)
    if path.suffix.lower() in _SPEC_SUFFIXES or path.exists():
        return _load_spec_file(path)
    lib = _library()["objects"]
    if text not in lib:
        raise ValueError(
            f"object: unknown object '{text}'; library objects are {', '.join(lib)}, "
            "or give a path to a .json/.yaml object specification file"
        )
    return _from_library_entry(text, lib[text])


def object_from_dict(data: dict[str, Any], name: str = "object", source: str = "") -> ObjectSpec:
    """Build an :class:`ObjectSpec` from a parsed specification file (docs/design/objects.md)."""
    if not isinstance(data, dict):
        raise ValueError(f"{source or name}: an object specification must be a mapping")
    known = {"name", "shape", "thickness", "mass", "density", "com_offset", "friction_table",
             "friction_pusher"}
    unknown = sorted(set(data) - known)
    if unknown:
        raise ValueError(f"{unknown[0]}: unknown field (known fields: {', '.join(sorted(known))})")
    name = str(data.get("name", name))
    shape_raw = _require(data, "shape")
    if not isinstance(shape_raw, dict):
        raise ValueError("shape: must be a mapping with a 'type' field")
    kind = _require(shape_raw, "type", "shape.type")
    if kind == "polygon":
        raw = Polygon(_require(shape_raw, "vertices", "shape.vertices"), field="shape.vertices")
    elif kind == "ellipse":
        axes = _vector2("shape.semi_axes", _require(shape_raw, "semi_axes", "shape.semi_axes"))
        raw = Ellipse(axes[0], axes[1], field="shape.semi_axes")
    else:
        raise ValueError(f"shape.type: unknown shape type '{kind}' (polygon or ellipse)")
    thickness = _number("thickness", _require(data, "thickness"))
    _positive("thickness", thickness)
    has_mass, has_density = "mass" in data, "density" in data
    if has_mass == has_density:
        raise ValueError("mass: give exactly one of 'mass' (kg) or 'density' (kg/m^3)")
    if has_mass:
        mass = _number("mass", data["mass"])
        _positive("mass", mass)
    else:
        density = _number("density", data["density"])
        _positive("density", density)
        mass = density * raw.area * thickness
    centroid = raw.centroid
    com_raw = _vector2("com_offset", data.get("com_offset", centroid))
    shape = raw.translated(-centroid) if isinstance(raw, Polygon) else raw
    return ObjectSpec(
        name=name,
        shape=shape,
        thickness=thickness,
        mass=mass,
        com=com_raw - centroid,
        friction_table=_number(
            "friction_table", data.get("friction_table", DEFAULT_FRICTION_TABLE)
        ),
        friction_pusher=_number(
            "friction_pusher", data.get("friction_pusher", DEFAULT_FRICTION_PUSHER)
        ),
        source=source or f"dict:{name}",
        source_origin=-centroid,
    )


def _from_library_entry(name: str, entry: dict[str, Any]) -> ObjectSpec:
    if "polygon_m" in entry:
        shape = {"type": "polygon", "vertices": entry["polygon_m"]}
    else:
        shape = {"type": "ellipse", "semi_axes": entry["ellipse_semi_axes_m"]}
    spec = {"name": name, "shape": shape, "thickness": entry["thickness_m"],
            "mass": entry["mass_kg"]}
    return object_from_dict(spec, name=name, source=f"library:{name}")


#: What each field of a specification file must be: the error of a file names the field and
#: this rule, never the file's text (a path can name any file on the machine).
_FIELD_RULES = {
    "shape": "must be a mapping with a 'type' field (polygon or ellipse)",
    "shape.type": "must be polygon or ellipse",
    "shape.vertices": "must be at least 3 finite [x, y] vertices (m) of a simple "
                      "counter-clockwise polygon with non-zero area",
    "shape.semi_axes": "must be two finite numbers > 0 [a, b] (m)",
    "thickness": "must be a finite number > 0 (m)",
    "mass": "give exactly one of 'mass' (kg, > 0) or 'density' (kg/m^3, > 0)",
    "density": "give exactly one of 'mass' (kg, > 0) or 'density' (kg/m^3, > 0)",
    "com_offset": "must be two finite numbers [x, y] (m) inside the convex hull of the outline",
    "friction_table": "must be a finite number >= 0",
    "friction_pusher": "must be a finite number >= 0",
}
_KNOWN_FIELDS = ("com_offset", "density", "friction_pusher", "friction_table", "mass", "name",
                 "shape", "thickness")


def _spec_file_error(path: Path, problem: str) -> ValueError:
    return ValueError(f"object: '{path}' is not a valid object specification: {problem}")


def _load_spec_file(path: Path) -> ObjectSpec:
    """Parse a specification file; its errors name a schema field and rule, never the file's
    content (no parser context, no value, no unknown key)."""
    if not path.is_file():
        raise ValueError(f"object: specification file '{path}' does not exist")
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError):
        raise _spec_file_error(path, "cannot read it as UTF-8 text") from None
    kind = "JSON" if path.suffix.lower() == ".json" else "YAML"
    try:
        if kind == "JSON":
            data = json.loads(text)
        else:
            import yaml

            data = yaml.safe_load(text)
    except Exception as exc:  # noqa: BLE001 - any parser error becomes a clear ValueError
        mark = getattr(exc, "problem_mark", None)
        line = getattr(exc, "lineno", None) or (mark.line + 1 if mark is not None else None)
        where = f" (line {line})" if line else ""
        raise _spec_file_error(path, f"cannot parse it as {kind}{where}") from None
    if not isinstance(data, dict):
        raise _spec_file_error(path, "an object specification must be a mapping of fields "
                               f"({', '.join(_KNOWN_FIELDS)})")
    unknown = [key for key in data if key not in _KNOWN_FIELDS]
    if unknown:
        raise _spec_file_error(path, f"{len(unknown)} unknown field(s); the known fields are "
                               f"{', '.join(_KNOWN_FIELDS)}")
    try:
        return object_from_dict(data, name=path.stem, source=str(path))
    except Exception as exc:  # noqa: BLE001 - whatever the values, one clean ValueError
        field, _, detail = str(exc).partition(":") if isinstance(exc, ValueError) else ("", "", "")
        if field not in _FIELD_RULES:
            raise _spec_file_error(path, "invalid shape or values") from None
        rule = ("missing required field" if detail.strip() == "missing required field"
                else _FIELD_RULES[field])
        raise _spec_file_error(path, f"{field}: {rule}") from None


_LIBRARY_CACHE: dict[str, Any] = {}


def _library() -> dict[str, Any]:
    if not _LIBRARY_CACHE:
        text = resources.files("push_core").joinpath("data", _LIBRARY_FILE).read_text()
        _LIBRARY_CACHE.update(json.loads(text))
    return _LIBRARY_CACHE


def _require(data: dict[str, Any], key: str, label: str | None = None) -> Any:
    if key not in data or data[key] is None:
        raise ValueError(f"{label or key}: missing required field")
    return data[key]


def _number(name: str, value: Any) -> float:
    if isinstance(value, bool):
        raise ValueError(f"{name}: expected a number, got {value!r}")
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a number, got {value!r}") from None
    if not np.isfinite(out):
        raise ValueError(f"{name}: must be finite, got {value!r}")
    return out


def _positive(name: str, value: float) -> None:
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"{name}: must be > 0, got {value}")


def _non_negative(name: str, value: float) -> None:
    if not (np.isfinite(value) and value >= 0):
        raise ValueError(f"{name}: must be >= 0, got {value}")


def _vector2(name: str, value: Any) -> np.ndarray:
    try:
        out = np.array(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected [x, y], got {value!r}") from None
    if out.shape != (2,) or not np.all(np.isfinite(out)):
        raise ValueError(f"{name}: expected two finite numbers [x, y], got {value!r}")
    return out


def _inside_hull(shape: Shape, point: np.ndarray) -> bool:
    """Whether ``point`` (2,) lies strictly inside the convex hull of the shape.

    The hull, not the outline: the area centroid (the object frame origin, the default COM) of
    an L or U shape lies outside its footprint but always inside its hull, and so does the
    centre of mass of any rigid body resting on that footprint.
    """
    if isinstance(shape, Ellipse):
        return bool((point[0] / shape.a) ** 2 + (point[1] / shape.b) ** 2 < 1.0)
    # Facets n . x + d <= 0 inside, with unit outward normals n.
    facets = ConvexHull(shape.vertices).equations
    return bool(np.all(facets[:, :2] @ point + facets[:, 2] < 0.0))


def _sample_area(shape: Shape, n: int, rng: np.random.Generator) -> np.ndarray:
    """n points uniformly distributed over the shape's area."""
    if isinstance(shape, Ellipse):
        r = np.sqrt(rng.random(n))
        phi = rng.random(n) * 2 * np.pi
        return np.stack([shape.a * r * np.cos(phi), shape.b * r * np.sin(phi)], axis=1)
    v = shape.vertices
    tris = v[shape.triangles()]  # (T, 3, 2)
    areas = 0.5 * np.abs(
        (tris[:, 1, 0] - tris[:, 0, 0]) * (tris[:, 2, 1] - tris[:, 0, 1])
        - (tris[:, 2, 0] - tris[:, 0, 0]) * (tris[:, 1, 1] - tris[:, 0, 1])
    )
    pick = rng.choice(len(tris), size=n, p=areas / areas.sum())
    u, w = rng.random(n), rng.random(n)
    flip = u + w > 1
    u, w = np.where(flip, 1 - u, u), np.where(flip, 1 - w, w)
    t = tris[pick]
    return t[:, 0] + u[:, None] * (t[:, 1] - t[:, 0]) + w[:, None] * (t[:, 2] - t[:, 0])
