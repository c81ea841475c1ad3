"""3MF codec: the triangle meshes of a 3MF package as arrays, and arrays as a 3MF package.

Reading (:func:`read_3mf`) parses the root model part with lxml (libxml2) and takes every
object of every build item, component transforms applied, concatenated in build order; the
vertex and triangle attributes are converted by numpy exactly as Python's ``float()`` and
``int()`` convert them, and scaled from the model's declared unit to millimetres, as slicers
read them (:func:`read_3mf_model` also gives the unit). Nothing is merged or repaired.
Writing (:func:`encode_3mf`) gives one object per body,
named, one build item each, in millimetres, with repr-exact float64 coordinates (a written
file reads back bit for bit); :func:`encode_3mf_components` stores each of a few meshes once
and each body as a component: a mesh and its transform.
"""

from __future__ import annotations

import io
import zipfile
import zlib
from collections.abc import Sequence
from xml.sax.saxutils import quoteattr

import numpy as np
from lxml import etree

__all__ = ["UNIT_MM", "ThreeMFError", "encode_3mf", "encode_3mf_components", "read_3mf",
           "read_3mf_model", "transform_text"]

CORE_NAMESPACE = "http://schemas.microsoft.com/3dmanufacturing/core/2015/02"
_REL_TYPE = "http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel"
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
#: components nested deeper than this are refused (a cycle of components never ends)
MAX_COMPONENT_DEPTH = 32

Body = tuple[np.ndarray, np.ndarray]


class ThreeMFError(ValueError):
    """The bytes are not a readable 3MF package; the message says what is wrong."""


# --------------------------------------------------------------------------------------------
# reading


def _model_xml(data: bytes) -> bytes:
    """The root model part of a 3MF package (``3D/3dmodel.model``, else the first .model)."""
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as archive:
            names = archive.namelist()
            model = next((n for n in names if n.lower() == "3d/3dmodel.model"), None)
            if model is None:
                model = next((n for n in names if n.lower().endswith(".model")), None)
            if model is None:
                raise ThreeMFError("the package has no 3D model part (3D/3dmodel.model)")
            return archive.read(model)
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
        ThreeMFError: a damaged zip, no model part, malformed XML, an unknown unit, a
            missing or unreadable attribute, a bad transform, or components that nest too
            deep.
    """
    xml = _model_xml(data)
    # no entity expansion and no network: a model part is data, never a fetch
    parser = etree.XMLParser(resolve_entities=False, no_network=True, remove_blank_text=True)
    try:
        root = etree.fromstring(xml, parser)
    except etree.XMLSyntaxError as exc:
        raise ThreeMFError(f"the model XML is malformed: {exc}") from exc
    declared = root.get("unit", "millimeter")
    unit = UNIT_ALIASES.get(declared.strip().lower(), declared.strip().lower())
    if unit not in UNIT_MM:
        raise ThreeMFError(f"the model's unit {declared!r} is not one of 3MF's units "
                           f"({', '.join(UNIT_MM)})")
    namespace = etree.QName(root).namespace
    ns = {"m": namespace} if namespace else {}
    prefix = "m:" if namespace else ""

    def tag(name: str) -> str:
        return f"{{{namespace}}}{name}" if namespace else name

    meshes: dict[str | None, Body] = {}
    components: dict[str | None, list[tuple[str | None, np.ndarray]]] = {}
    for obj in root.iterfind(f"{tag('resources')}/{tag('object')}"):
        oid = obj.get("id")
        mesh = obj.find(tag("mesh"))
        if mesh is not None:
            meshes[oid] = (
                _numbers(mesh, f"{prefix}vertices/{prefix}vertex", ("x", "y", "z"), ns, False),
                _numbers(mesh, f"{prefix}triangles/{prefix}triangle", ("v1", "v2", "v3"), ns,
                         True),
            )
        parts = obj.find(tag("components"))
        if parts is not None:
            components[oid] = [(c.get("objectid"), _transform(c.get("transform")))
                               for c in parts.iterfind(tag("component"))]

    out_v: list[np.ndarray] = []
    out_f: list[np.ndarray] = []
    offset = 0

    def emit(oid: str | None, transform: np.ndarray, depth: int) -> None:
        nonlocal offset
        if depth > MAX_COMPONENT_DEPTH:
            raise ThreeMFError(f"components nest more than {MAX_COMPONENT_DEPTH} deep "
                               "(a cycle?)")
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

    for item in root.iterfind(f"{tag('build')}/{tag('item')}"):
        emit(item.get("objectid"), _transform(item.get("transform")), 0)
    if not out_f:
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


def _package(parts: list[str]) -> bytes:
    buffer = io.BytesIO()
    # level 1: much faster than the default on big meshes, for a somewhat larger file
    with zipfile.ZipFile(buffer, "w", compression=zipfile.ZIP_DEFLATED,
                         compresslevel=1) as archive:
        archive.writestr("[Content_Types].xml", CONTENT_TYPES)
        archive.writestr("_rels/.rels", RELATIONSHIPS)
        archive.writestr("3D/3dmodel.model", "".join(parts))
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
