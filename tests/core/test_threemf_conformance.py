"""3MF packages that break the core specification where lib3mf (what slicers and printers
use) refuses them or reads them otherwise: the reader refuses each with a message naming the
file and what is wrong, so that ``jampacked validate`` never passes them (exit status 2, as
for a damaged 3MF); the package's own 3D model relationship picks the model part."""

from __future__ import annotations

import io
import zipfile
from pathlib import Path

import numpy as np
import pytest
import trimesh

from jampacked.cli.main import main
from jampacked.core import threemf
from jampacked.core.errors import MeshError
from jampacked.core.mesh_files import read_mesh_arrays
from jampacked.export.io import write_mesh
from jampacked.export.validate import validate_file

CT = "[Content_Types].xml"
RELS = "_rels/.rels"
MODEL = "3D/3dmodel.model"
PRODUCTION = "http://schemas.microsoft.com/3dmanufacturing/production/2015/06"


def _tetra(scale: float = 1.0) -> str:
    """A closed, outward tetrahedron mesh element with edges ``scale`` long."""
    v = "".join(f'<vertex x="{x * scale!r}" y="{y * scale!r}" z="{z * scale!r}"/>'
                for x, y, z in [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)])
    t = "".join(f'<triangle v1="{a}" v2="{b}" v3="{c}"/>'
                for a, b, c in [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)])
    return f"<mesh><vertices>{v}</vertices><triangles>{t}</triangles></mesh>"


def _model(resources: str, build: str, namespace: str = threemf.CORE_NAMESPACE) -> str:
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<model unit="millimeter" '
            f'xmlns="{namespace}" xmlns:p="{PRODUCTION}"><resources>{resources}</resources>'
            f"<build>{build}</build></model>\n")


def _rels(target: str) -> str:
    return threemf.RELATIONSHIPS.replace('Target="/3D/3dmodel.model"', f'Target="{target}"')


def _package(path: Path, parts: dict[str, str]) -> Path:
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for name, text in parts.items():
            archive.writestr(name, text)
    return path


def _standard(path: Path, model: str) -> Path:
    """A package as 3MF writers make it: content types, relationships, the model part."""
    return _package(path, {CT: threemf.CONTENT_TYPES, RELS: threemf.RELATIONSHIPS,
                           MODEL: model})


GOOD = _model(f'<object id="1" type="model">{_tetra()}</object>', '<item objectid="1"/>')


def _refused(path: Path, *phrases: str) -> str:
    """Reading ``path`` and validating it fail with a MeshError naming the file and saying
    each phrase; ``jampacked validate`` exits 2, as for a damaged 3MF."""
    with pytest.raises(MeshError) as info:
        read_mesh_arrays(path)
    message = str(info.value)
    assert path.name in message and "cannot be read as a 3MF file" in message
    for phrase in phrases:
        assert phrase in message, (phrase, message)
    with pytest.raises(MeshError, match="cannot be read as a 3MF file"):
        validate_file(path)
    assert main(["validate", str(path)]) == 2
    return message


def test_build_item_of_a_missing_object_is_refused(tmp_path):
    model = _model(f'<object id="1" type="model">{_tetra()}</object>',
                   '<item objectid="1"/><item objectid="7"/>')
    _refused(_standard(tmp_path / "missing_ref.3mf", model),
             "build item 2 refers to object 7, which does not exist")


def test_duplicate_object_id_is_refused(tmp_path):
    model = _model(f'<object id="1" type="model">{_tetra()}</object>'
                   f'<object id="1" type="model">{_tetra(2.0)}</object>',
                   '<item objectid="1"/>')
    _refused(_standard(tmp_path / "dup_id.3mf", model), "two objects have the id 1")


def test_package_without_content_types_is_refused(tmp_path):
    path = _package(tmp_path / "no_ct.3mf", {RELS: threemf.RELATIONSHIPS, MODEL: GOOD})
    _refused(path, "no [Content_Types].xml")


def test_package_without_relationships_is_refused(tmp_path):
    path = _package(tmp_path / "no_rels.3mf", {CT: threemf.CONTENT_TYPES, MODEL: GOOD})
    _refused(path, "no _rels/.rels")


def test_model_outside_the_core_namespace_is_refused(tmp_path):
    model = _model(f'<object id="1" type="model">{_tetra()}</object>',
                   '<item objectid="1"/>', namespace="http://example.com/bogus")
    _refused(_standard(tmp_path / "bad_ns.3mf", model), "3D/3dmodel.model",
             "not a <model> in 3MF's core namespace")
    no_namespace = GOOD.replace(f'xmlns="{threemf.CORE_NAMESPACE}" ', "")
    _refused(_standard(tmp_path / "no_ns.3mf", no_namespace), "core namespace")


def test_component_before_its_object_is_refused(tmp_path):
    model = _model('<object id="2" type="model"><components><component objectid="1"/>'
                   f'</components></object><object id="1" type="model">{_tetra()}</object>',
                   '<item objectid="2"/>')
    _refused(_standard(tmp_path / "fwd_ref.3mf", model),
             "component 1 of object 2 refers to object 1, which is defined after it")
    itself = _model('<object id="1" type="model"><components><component objectid="1"/>'
                    "</components></object>", '<item objectid="1"/>')
    _refused(_standard(tmp_path / "cycle.3mf", itself), "defined after it")


def test_object_with_mesh_and_components_is_refused(tmp_path):
    model = _model(f'<object id="1" type="model">{_tetra()}</object>'
                   f'<object id="2" type="model">{_tetra()}<components>'
                   '<component objectid="1" transform="1 0 0 0 1 0 0 0 1 30 0 0"/>'
                   "</components></object>", '<item objectid="2"/>')
    _refused(_standard(tmp_path / "mesh_and_comp.3mf", model),
             "object 2 has both a mesh and components")


def test_build_item_of_type_other_is_refused(tmp_path):
    model = _model(f'<object id="1" type="other">{_tetra()}</object>', '<item objectid="1"/>')
    _refused(_standard(tmp_path / "other_type.3mf", model),
             'build item 1 is object 1 of type "other"', 'set the object\'s type to "model"')


def test_the_model_part_is_the_relationship_target(tmp_path):
    """The package's 3D model relationship names the part lib3mf loads and prints; another
    part at the conventional name is not it."""
    path = _package(tmp_path / "rel_other.3mf", {
        CT: threemf.CONTENT_TYPES, RELS: _rels("/3D/other.model"), MODEL: GOOD,
        "3D/other.model": _model(f'<object id="1" type="model">{_tetra(2.0)}</object>',
                                 '<item objectid="1"/>')})
    v, f = read_mesh_arrays(path)
    assert np.ptp(v, axis=0).tolist() == [2.0, 2.0, 2.0]
    assert validate_file(path).volume == pytest.approx(8 / 6)


@pytest.mark.parametrize("target", ["3D/model%20one.model", "/3d/MODEL ONE.model",
                                    "./3D/model one.model"])
def test_relationship_targets_relative_encoded_or_in_other_case(tmp_path, target):
    path = _package(tmp_path / "target.3mf", {CT: threemf.CONTENT_TYPES, RELS: _rels(target),
                                              "3D/model one.model": GOOD})
    assert validate_file(path).passed


def test_relationship_problems_are_refused(tmp_path):
    _refused(_package(tmp_path / "gone.3mf", {CT: threemf.CONTENT_TYPES,
                                              RELS: _rels("/3D/gone.model"), MODEL: GOOD}),
             "names /3D/gone.model as the 3D model part, which the package lacks")
    no_model_rel = threemf.RELATIONSHIPS.replace("3dmanufacturing/2013/01/3dmodel", "other")
    _refused(_package(tmp_path / "none.3mf", {CT: threemf.CONTENT_TYPES, RELS: no_model_rel,
                                              MODEL: GOOD}),
             "has 0 3D model relationships")
    two = threemf.RELATIONSHIPS.replace("</Relationships>", threemf.RELATIONSHIPS.split(
        "<Relationships")[1].split(">", 1)[1].replace('Id="rel0"', 'Id="rel1"'))
    _refused(_package(tmp_path / "two.3mf", {CT: threemf.CONTENT_TYPES, RELS: two,
                                             MODEL: GOOD}),
             "has 2 3D model relationships")
    _refused(_package(tmp_path / "bad_rels.3mf", {CT: threemf.CONTENT_TYPES,
                                                  RELS: "<Relationships>", MODEL: GOOD}),
             "the XML of _rels/.rels is malformed")


def test_writers_packages_still_read(tmp_path):
    """jampacked's own 3MFs (one object per body, and components), trimesh's, support
    objects in the build, and a production-extension reference into another part (as
    Bambu-style writers make; not followed, as before) are read, not refused."""
    box = trimesh.creation.box((1.0, 2.0, 3.0))
    v, f = np.asarray(box.vertices), np.asarray(box.faces, np.int64)
    own = tmp_path / "own.3mf"
    write_mesh(own, [(v, f), (v + [5.0, 0, 0], f)])
    assert validate_file(own).passed and len(validate_file(own).bodies) == 2
    data = threemf.encode_3mf_components([(v, f)], ["box"], [0, 0],
                                         np.stack([np.eye(4), np.eye(4)]) + [[0, 0, 0, 5.0],
                                                                            [0] * 4, [0] * 4,
                                                                            [0] * 4])
    assert threemf.read_3mf(data)[1].shape == (24, 3)
    scene = trimesh.Scene([box, box.copy().apply_translation([5.0, 0, 0])])
    (tmp_path / "trimesh.3mf").write_bytes(trimesh.exchange.threemf.export_3MF(scene))
    assert validate_file(tmp_path / "trimesh.3mf").passed
    support = _model(f'<object id="1" type="model">{_tetra()}</object>'
                     f'<object id="2" type="support">{_tetra()}</object>',
                     '<item objectid="1"/><item objectid="2" '
                     'transform="1 0 0 0 1 0 0 0 1 5 0 0"/>')
    assert validate_file(_standard(tmp_path / "support.3mf", support)).passed
    bambu = _model(f'<object id="1" type="model">{_tetra()}</object>'
                   '<object id="2" type="model"><components><component objectid="1"/>'
                   '<component p:path="/3D/Objects/object_1.model" objectid="9"/>'
                   "</components></object>", '<item objectid="2"/>')
    v, f = read_mesh_arrays(_standard(tmp_path / "bambu.3mf", bambu))
    assert v.shape == (4, 3) and f.shape == (4, 3)


def test_a_project_whose_objects_are_all_in_other_parts_is_named(tmp_path):
    # a Bambu Studio / OrcaSlicer project keeps its meshes in 3D/Objects/*.model: it was
    # validated as "FAIL: no triangles (empty, points or lines only)"
    project = _model('<object id="2" type="model"><components>'
                     '<component p:path="/3D/Objects/object_1.model" objectid="9"/>'
                     "</components></object>", '<item objectid="2"/>')
    _refused(_standard(tmp_path / "project.3mf", project),
             "/3D/Objects/object_1.model", "production extension", "plain 3MF or as STL")


def test_the_same_meshes_give_the_same_package_bytes():
    """A 3MF's zip entries carried the time they were written, so two exports of one packing
    differed (STL, OBJ and PLY did not): the entries' time is fixed, their compression and
    permissions as before."""
    box = trimesh.creation.box((10.0, 20.0, 30.0))
    v, f = np.asarray(box.vertices), np.asarray(box.faces)
    data = threemf.encode_3mf([(v, f)], ["box"])
    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        infos = archive.infolist()
    assert [i.filename for i in infos] == [CT, RELS, MODEL]
    assert all(i.date_time == (1980, 1, 1, 0, 0, 0) for i in infos)
    assert all(i.compress_type == zipfile.ZIP_DEFLATED for i in infos)
    assert all(i.external_attr == 0o600 << 16 for i in infos)
    components = threemf.encode_3mf_components([(v, f)], ["box"], [0], [np.eye(4)])
    with zipfile.ZipFile(io.BytesIO(components)) as archive:
        assert {i.date_time for i in archive.infolist()} == {(1980, 1, 1, 0, 0, 0)}
