"""3MF codec: the triangle meshes of a 3MF package as arrays, and arrays as a 3MF package.

Reading (:func:`read_3mf`) finds the root model part as the package says (the target of the
one 3D model relationship in ``_rels/.rels``), parses it with lxml (libxml2) and takes every
object of every build item, component transforms applied, concatenated in build order; the
vertex and triangle attributes are converted by numpy exactly as Python's ``float()`` and
``int()`` convert them, and scaled from the model's declared unit to millimetres, as slicers
read them (:func:`read_3mf_model` also gives the unit). Nothing is merged or repaired.
A package that breaks the core specification where lib3mf (what slicers and printers use)
refuses it or reads it otherwise is refused, never guessed at: no ``[Content_Types].xml`` or
``_rels/.rels``, no or several 3D model relationships, a model outside the core namespace, two
objects with one id, an object with both a mesh and components, a component or build item
that refers to an object not defined before it, a build item of an object of type "other".
A reference into another model part (the production extension's ``p:path``) is not followed.
Writing (:func:`encode_3mf`) gives one object per body,
named, one build item each, in millimetres, with repr-exact float64 coordinates (a written
file reads back bit for bit); :func:`encode_3mf_components` stores each of a few meshes once
and each body as a component: a mesh and its transform.
"""

from __future__ import annotations

import io
import posixpath
import zipfile
import zlib
from collections.abc import Sequence
from urllib.parse import unquote
from xml.sax.saxutils import quoteattr

import numpy as np
from lxml import etree

__all__ = ["UNIT_MM", "ThreeMFError", "encode_3mf", "encode_3mf_components", "read_3mf",
           "read_3mf_model", "transform_text"]

CORE_NAMESPACE = "http://schemas.microsoft.com/3dmanufacturing/core/2015/02"
_REL_TYPE = "http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel"
_PRODUCTION_NAMESPACE = "http://schemas.microsoft.com/3dmanufacturing/production/2015/06"
_PATH = f"{{{_PRODUCTION_NAMESPACE}}}path"  # a reference into another model part
_CONTENT_TYPES_PART = "[Content_Types].xml"
_RELS_PART = "_rels/.rels"
CONTENT_TYPES = (
    '<?xml version="1.0" encoding="UTF-8"?>\n'
    '<Types xmlns="http://schemas.openxmlformats.org/package/2006/content-types">'
    '<Default Extension="rels" '
    'ContentType="application/vnd.openxmlformats-package.relationships+xml"/>'
    '<Default Extension="model" '
    'ContentType="application/vnd.ms-package.3dmanufacturing-3dmodel+xml"/>'
    "</Types>\n"
)
RELATIONSHIPS = (
    '<?xml version="1.0" encoding="UTF-8"?>\n'
    '<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships">'
    f'<Relationship Target="/3D/3dmodel.model" Id="rel0" Type="{_REL_TYPE}"/>'
    "</Relationships>\n"
)
#: the core specification's model units, in millimetres (``unit`` absent: millimetres)
UNIT_MM = {"micron": 1e-3, "millimeter": 1.0, "centimeter": 10.0, "inch": 25.4,
           "foot": 304.8, "meter": 1000.0}
#: what some writers put in place of the specification's unit names (read as those)
UNIT_ALIASES = {"um": "micron", "µm": "micron", "micrometer": "micron", "micrometre": "micron",
                "mm": "millimeter", "millimetre": "millimeter", "millimeters": "millimeter",
                "millimetres": "millimeter", "cm": "centimeter", "centimetre": "centimeter",
                "centimeters": "centimeter", "centimetres": "centimeter", "in": "inch",
                "inches": "inch", "ft": "foot", "feet": "foot", "m": "meter", "metre": "meter",
                "meters": "meter", "metres": "meter"}
#: components nested deeper than this are refused (a writer's runaway, or a hostile file)
MAX_COMPONENT_DEPTH = 32

Body = tuple[np.ndarray, np.ndarray]


class ThreeMFError(ValueError):
    """The bytes are not a readable 3MF package; the message says what is wrong."""


# --------------------------------------------------------------------------------------------
# reading


def _parse_xml(xml: bytes, part: str) -> etree._Element:
    """The root element of an XML part; no entity expansion and no network (a part is data,
    never a fetch)."""
    parser = etree.XMLParser(resolve_entities=False, no_network=True, remove_blank_text=True)
    try:
        return etree.fromstring(xml, parser)
    except etree.XMLSyntaxError as exc:
        raise ThreeMFError(f"the XML of {part} is malformed: {exc}") from exc


def _start_part(archive: zipfile.ZipFile, names: dict[str, str]) -> str:
    """The zip name of the 3D model part: the target of the package's one 3D model
    relationship in ``_rels/.rels`` (``names``: lower-cased name -> name, part names being
    case-insensitive)."""
    for required in (_CONTENT_TYPES_PART, _RELS_PART):
        if required.lower() not in names:
            raise ThreeMFError(f"the package has no {required}, which every 3MF package "
                               "needs (lib3mf refuses it)")
    rels = _parse_xml(archive.read(names[_RELS_PART.lower()]), _RELS_PART)
    targets = [r.get("Target", "") for r in rels.iter("{*}Relationship")
               if r.get("Type", "").strip().lower() == _REL_TYPE.lower()]
    if len(targets) != 1:
        raise ThreeMFError(f"{_RELS_PART} has {len(targets)} 3D model relationships (type "
                           f"{_REL_TYPE}) where a 3MF package has exactly one")
    # a target relative to the package root, or absolute; percent-encoded as a URI
    name = posixpath.normpath("/" + unquote(targets[0].strip())).lstrip("/")
    if name.lower() not in names:
        raise ThreeMFError(f"{_RELS_PART} names /{name} as the 3D model part, which the "
                           "package lacks")
    return names[name.lower()]


def _model_xml(data: bytes) -> tuple[bytes, str]:
    """The root model part of a 3MF package (the start part :func:`_start_part` names) and
    its name."""
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as archive:
            names = {n.lower(): n for n in archive.namelist()}
            part = _start_part(archive, names)
            return archive.read(part), part
    except ThreeMFError:  # a ValueError itself: keep its own message
        raise
    # ValueError: a damaged name that claims to be UTF-8 (UnicodeDecodeError), bad offsets
    except (zipfile.BadZipFile, zlib.error, EOFError, NotImplementedError, OSError,
            ValueError) as exc:
        raise ThreeMFError(f"the zip archive is damaged: {exc}") from exc


def _transform(text: str | None) -> np.ndarray:
    """A 3MF transform ("m00 m01 m02 m10 ... m32", row vectors) as a 4x4 column matrix."""
    m = np.eye(4)
    if text:
        try:
            values = np.array(text.split(), dtype=np.float64)
        except ValueError:
            values = np.zeros(0)
        if len(values) != 12:
            raise ThreeMFError(f"transform {text!r} is not 12 numbers")
        m[:3, :4] = values.reshape(4, 3).T
    return m


def _numbers(element: etree._Element, path: str, names: tuple[str, str, str],
             ns: dict[str, str], integer: bool) -> np.ndarray:
    """(N, 3) attribute values of the child elements at ``path`` (float64, or int64 indices,
    where an index written as an integral decimal such as "1.0" is accepted)."""
    n = int(element.xpath(f"count({path})", namespaces=ns))
    columns = []
    for name in names:
        # plain strings: lxml's default "smart" strings keep a reference to their element
        text = etree.XPath(f"{path}/@{name}", namespaces=ns, smart_strings=False)(element)
        if len(text) != n:
            raise ThreeMFError(f"{n - len(text)} of {n} elements lack the attribute {name!r}")
        columns.append(text)
    try:
        if integer:
            try:
                values = np.array(columns, dtype=np.int64)
            except (ValueError, OverflowError):
                real = np.array(columns, dtype=np.float64)
                if not np.all(real == np.floor(real)):
                    raise ValueError("a vertex index is not an integer") from None
                values = real.astype(np.int64)
        else:
            values = np.array(columns, dtype=np.float64)
    except (ValueError, OverflowError) as exc:
        raise ThreeMFError(f"a number cannot be read ({exc})") from exc
    return np.ascontiguousarray(values.T.reshape(-1, 3))


def _tag(name: str) -> str:
    return f"{{{CORE_NAMESPACE}}}{name}"


_NS = {"m": CORE_NAMESPACE}


def _unit(root: etree._Element) -> str:
    """The model's unit, one of :data:`UNIT_MM` (a writer's spelling read as the spec's)."""
    declared = root.get("unit", "millimeter")
    unit = UNIT_ALIASES.get(declared.strip().lower(), declared.strip().lower())
    if unit not in UNIT_MM:
        raise ThreeMFError(f"the model's unit {declared!r} is not one of 3MF's units "
                           f"({', '.join(UNIT_MM)})")
    return unit


def _reference(element: etree._Element, where: str, part: str, defined: dict[str, str],
               ids: set[str]) -> str | None:
    """The object id a component or build item refers to, which must be an object of
    ``part`` defined before it (``defined``: id -> type so far; ``ids``: every object id of
    the part); None for a reference into another model part (not followed)."""
    path = element.get(_PATH)
    if path and path.strip().lstrip("/").lower() != part.lower():
        return None
    oid = element.get("objectid")
    if oid is None:
        raise ThreeMFError(f"{where} has no objectid")
    if oid not in defined:
        where_is = ("is defined after it, and 3MF requires every object to be defined before "
                    "it is referred to" if oid in ids else "does not exist")
        raise ThreeMFError(f"{where} refers to object {oid}, which {where_is}")
    return oid


_Resources = tuple[dict[str, Body], dict[str, list[tuple[str, np.ndarray]]], dict[str, str]]


def _resources(root: etree._Element, part: str) -> _Resources:
    """The objects of the model part, checked: ``(meshes, components, types)``, each keyed by
    object id (``components``: the (object id, 4x4 transform) of each component that
    refers to an object of this part)."""
    meshes: dict[str, Body] = {}
    components: dict[str, list[tuple[str, np.ndarray]]] = {}
    types: dict[str, str] = {}
    objects = list(root.iterfind(f"{_tag('resources')}/{_tag('object')}"))
    ids = {obj.get("id") for obj in objects} - {None}
    for k, obj in enumerate(objects, 1):
        oid = obj.get("id")
        if oid is None:
            raise ThreeMFError(f"object {k} of the resources has no id")
        if oid in types:
            raise ThreeMFError(f"two objects have the id {oid} (resource ids are unique in a "
                               "3MF model, and lib3mf refuses it)")
        mesh, parts = obj.find(_tag("mesh")), obj.find(_tag("components"))
        if mesh is not None and parts is not None:
            raise ThreeMFError(f"object {oid} has both a mesh and components (3MF allows one "
                               "or the other: which is meant is ambiguous); give the mesh "
                               "and the components an object each")
        if mesh is not None:
            meshes[oid] = (
                _numbers(mesh, "m:vertices/m:vertex", ("x", "y", "z"), _NS, False),
                _numbers(mesh, "m:triangles/m:triangle", ("v1", "v2", "v3"), _NS, True),
            )
        elif parts is not None:
            refs = [(_reference(c, f"component {j} of object {oid}", part, types, ids),
                     _transform(c.get("transform")))
                    for j, c in enumerate(parts.iterfind(_tag("component")), 1)]
            components[oid] = [(child, m) for child, m in refs if child is not None]
        types[oid] = obj.get("type", "model").strip()
    return meshes, components, types


def _build(root: etree._Element, part: str, types: dict[str, str]
           ) -> list[tuple[str, np.ndarray]]:
    """The (object id, 4x4 transform) of each build item that refers to an object of this
    part, checked: an existing object, not of type "other"."""
    items = []
    for k, item in enumerate(root.iterfind(f"{_tag('build')}/{_tag('item')}"), 1):
        oid = _reference(item, f"build item {k}", part, types, set(types))
        if oid is None:
            continue
        if types[oid] == "other":
            raise ThreeMFError(f"build item {k} is object {oid} of type \"other\", which 3MF "
                               "does not allow in the build (such an object is not to be "
                               "printed); set the object's type to \"model\" if it is to be "
                               "printed, or remove the build item")
        items.append((oid, _transform(item.get("transform"))))
    return items


def read_3mf(data: bytes) -> Body:
    """All build items of a 3MF package in millimetres: :func:`read_3mf_model` without the
    unit."""
    return read_3mf_model(data)[0]


def read_3mf_model(data: bytes) -> tuple[Body, str]:
    """All build items of a 3MF package (root model part only), transforms applied, and the
    unit the model declares.

    Args:
        data: the bytes of a .3mf file.

    Returns:
        ``((vertices, faces), unit)``: (V, 3) float64 in millimetres (the declared unit
        converted; bit for bit the file's numbers in a millimetre model) in the file's frame,
        (F, 3) int64 indices into the concatenated vertices, objects in build order; and
        the unit, one of :data:`UNIT_MM`.

    Raises:
        ThreeMFError: a damaged zip; no [Content_Types].xml, no _rels/.rels, or not exactly
            one 3D model relationship to a part the package holds; malformed XML; a model
            outside 3MF's core namespace; an unknown unit; a missing or unreadable
            attribute; a bad transform; a duplicate object id, an object with both a mesh
            and components, a reference to an object not defined before it, a build item
            of type "other"; or components that nest too deep.
    """
    xml, part = _model_xml(data)
    root = _parse_xml(xml, part)
    if root.tag != _tag("model"):
        raise ThreeMFError(f"the root element of {part} is {root.tag!r}, not a <model> in "
                           f"3MF's core namespace {CORE_NAMESPACE} (lib3mf finds no objects "
                           f"in it)")
    unit = _unit(root)
    meshes, components, types = _resources(root, part)

    out_v: list[np.ndarray] = []
    out_f: list[np.ndarray] = []
    offset = 0

    def emit(oid: str, transform: np.ndarray, depth: int) -> None:
        nonlocal offset
        if depth > MAX_COMPONENT_DEPTH:
            raise ThreeMFError(f"components nest more than {MAX_COMPONENT_DEPTH} deep")
        if oid in meshes:
            v, f = meshes[oid]
            if np.array_equal(transform, np.eye(4)) and np.all(np.isfinite(v)):
                # what the product with the identity gives for finite numbers (-0.0 -> 0.0)
                out_v.append(v + 0.0)
            else:
                out_v.append(v @ transform[:3, :3].T + transform[:3, 3])
            out_f.append(f + offset)
            offset += len(v)
        for child, m in components.get(oid, []):
            emit(child, transform @ m, depth + 1)

    for oid, transform in _build(root, part, types):
        emit(oid, transform, 0)
    if not out_f:
        elsewhere = [e.get(_PATH) for e in root.iter() if e.get(_PATH) and
                     e.get(_PATH).strip().lstrip("/").lower() != part.lower()]
        if elsewhere:
            raise ThreeMFError(
                f"its objects are in other model parts ({elsewhere[0]}: the 3MF production "
                "extension, as Bambu Studio and OrcaSlicer write a project), and only the "
                "root model part is read; export the plate as a plain 3MF or as STL")
        return (np.zeros((0, 3)), np.zeros((0, 3), np.int64)), unit
    # one body: already new arrays
    v, f = (out_v[0], out_f[0]) if len(out_f) == 1 else (np.concatenate(out_v),
                                                          np.concatenate(out_f))
    if UNIT_MM[unit] != 1.0:
        v *= UNIT_MM[unit]
    return (v, f), unit


# --------------------------------------------------------------------------------------------
# writing


_HEAD = ('<?xml version="1.0" encoding="UTF-8"?>\n'
         f'<model unit="millimeter" xml:lang="en-US" xmlns="{CORE_NAMESPACE}">\n'
         "<resources>\n")


def _mesh_object(oid: int, name: str, v: np.ndarray, f: np.ndarray,
                 triangles: dict[bytes, str]) -> list[str]:
    """The text of an object holding one mesh; ``triangles`` caches the triangles' text of
    faces already written (the objects of one type share their faces)."""
    out = [f'<object id="{oid}" type="model" name={quoteattr(name)}>\n<mesh>\n<vertices>\n']
    # repr-exact float64 text (the shortest round-trip digits)
    v = np.asarray(v, np.float64)
    out.append(('<vertex x="%r" y="%r" z="%r"/>\n' * len(v)) % tuple(v.ravel().tolist()))
    out.append("</vertices>\n<triangles>\n")
    f = np.ascontiguousarray(f, np.int64)
    key = f.tobytes()
    if key not in triangles:
        triangles[key] = (('<triangle v1="%d" v2="%d" v3="%d"/>\n' * len(f))
                          % tuple(f.ravel().tolist()))
    out.append(triangles[key])
    out.append("</triangles>\n</mesh>\n</object>\n")
    return out


def transform_text(matrix: np.ndarray) -> str:
    """A (4, 4) column matrix (``p' = M @ [p, 1]``) as a 3MF transform ("m00 m01 m02 m10 ...
    m32", row vectors), repr-exact: :func:`_transform` reads back the same numbers."""
    m = np.asarray(matrix, np.float64)
    return " ".join(repr(x) for x in m[:3, :4].T.ravel().tolist())


#: the zip entries' time stamp: fixed, so that the same meshes give the same bytes (an entry
#: named by a string takes the current time)
ZIP_DATE_TIME = (1980, 1, 1, 0, 0, 0)


def _package(parts: list[str]) -> bytes:
    buffer = io.BytesIO()
    # level 1: much faster than the default on big meshes, for a somewhat larger file
    with zipfile.ZipFile(buffer, "w", compression=zipfile.ZIP_DEFLATED,
                         compresslevel=1) as archive:
        for name, text in (("[Content_Types].xml", CONTENT_TYPES), ("_rels/.rels", RELATIONSHIPS),
                           ("3D/3dmodel.model", "".join(parts))):
            entry = zipfile.ZipInfo(name, date_time=ZIP_DATE_TIME)
            entry.external_attr = 0o600 << 16  # what a name given as a string gets
            archive.writestr(entry, text, compress_type=zipfile.ZIP_DEFLATED, compresslevel=1)
    return buffer.getvalue()


def encode_3mf(bodies: Sequence[Body], names: Sequence[str] | None = None) -> bytes:
    """A 3MF package (bytes) with one named object and one build item per body.

    Args:
        bodies: ``(vertices, faces)`` per body: (V, 3) float64 in millimetres, (F, 3) int64
            indices into that body's vertices, counter-clockwise seen from outside.
        names: one object name per body (default "body 1", "body 2", ...).
    """
    parts = [_HEAD]
    triangles: dict[bytes, str] = {}
    for k, (v, f) in enumerate(bodies):
        name = str(names[k]) if names is not None else f"body {k + 1}"
        parts += _mesh_object(k + 1, name, v, f, triangles)
    parts.append("</resources>\n<build>\n")
    parts += [f'<item objectid="{k + 1}"/>\n' for k in range(len(bodies))]
    parts.append("</build>\n</model>\n")
    return _package(parts)


def encode_3mf_components(meshes: Sequence[Body], mesh_names: Sequence[str],
                          index: Sequence[int], matrices: np.ndarray,
                          names: Sequence[str] | None = None) -> bytes:
    """A 3MF package that stores each mesh once and each body as a named object with one
    component: mesh ``index[k]`` moved by ``matrices[k]`` ((4, 4), column vectors); one
    build item per body. Readers (:func:`read_3mf` included) apply the transforms, so the
    file holds the same bodies as :func:`encode_3mf` of the moved meshes, up to the rounding
    of the product, in a fraction of the text.

    Args:
        meshes: ``(vertices, faces)`` per mesh, as for :func:`encode_3mf` (the meshes' own
            frame); mesh_names: one object name per mesh.
        index: (N,) the mesh of each body; matrices: (N, 4, 4) each body's transform.
        names: one object name per body (default "body 1", "body 2", ...).
    """
    parts = [_HEAD]
    triangles: dict[bytes, str] = {}
    for k, ((v, f), name) in enumerate(zip(meshes, mesh_names, strict=True)):
        parts += _mesh_object(k + 1, str(name), v, f, triangles)
    first = len(meshes) + 1
    for k, (mesh, m) in enumerate(zip(index, matrices, strict=True)):
        name = quoteattr(str(names[k]) if names is not None else f"body {k + 1}")
        parts.append(f'<object id="{first + k}" type="model" name={name}>\n<components>\n'
                     f'<component objectid="{int(mesh) + 1}" '
                     f'transform="{transform_text(m)}"/>\n</components>\n</object>\n')
    parts.append("</resources>\n<build>\n")
    parts += [f'<item objectid="{first + k}"/>\n' for k in range(len(index))]
    parts.append("</build>\n</model>\n")
    return _package(parts)
