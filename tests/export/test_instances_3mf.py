"""Parts as instances: a 3MF stores each type's mesh once and each part as a component (the
mesh and its transform); every reader gets the same bodies as from the moved meshes."""

from __future__ import annotations

import io
import zipfile

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from jampacked.core.errors import InputError
from jampacked.core.mesh_files import read_mesh_arrays
from jampacked.core.threemf import _transform, read_3mf, transform_text
from jampacked.export.io import write_mesh
from jampacked.export.mesh_write import Instances, encode_mesh


def _instances(n: int = 6) -> Instances:
    box = trimesh.creation.box((1.0, 2.0, 3.0))
    ball = trimesh.creation.icosphere(2, radius=1.2)
    meshes = [(np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64))
              for m in (box, ball)]
    rng = np.random.default_rng(3)
    mats = np.tile(np.eye(4), (n, 1, 1))
    mats[:, :3, :3] = Rotation.random(n, random_state=4).as_matrix()
    mats[:, :3, 3] = np.arange(n)[:, None] * 5.0 + rng.normal(size=(n, 3)) * 0.1
    return Instances(meshes, ["box", "ball"], np.arange(n) % 2, mats)


def test_transform_text_reads_back_exactly():
    m = np.eye(4)
    m[:3, :3] = Rotation.random(random_state=1).as_matrix()
    m[:3, 3] = [1 / 3, -2e-7, 12345.678901234567]
    np.testing.assert_array_equal(_transform(transform_text(m)), m)


def test_3mf_of_instances_reads_back_as_the_moved_meshes_bit_for_bit():
    inst = _instances()
    data = encode_mesh("3mf", inst, [f"part_{k}" for k in range(6)])
    v, f = read_3mf(data)
    bodies = inst.bodies()
    np.testing.assert_array_equal(v, np.concatenate([b[0] for b in bodies]))
    offsets = np.cumsum([0] + [len(b[0]) for b in bodies[:-1]])
    np.testing.assert_array_equal(f, np.concatenate([b[1] + o for b, o in
                                                     zip(bodies, offsets, strict=True)]))
    with zipfile.ZipFile(io.BytesIO(data)) as z:
        model = z.read("3D/3dmodel.model").decode()
    assert model.count("<mesh>") == 2 and model.count("<component ") == 6
    assert all(f'name="part_{k}"' in model for k in range(6))


@pytest.mark.parametrize("ext", ["stl", "ply", "obj", "3mf"])
def test_instances_write_and_validate_in_every_format(tmp_path, ext):
    inst = _instances()
    out = tmp_path / f"parts.{ext}"
    rep = write_mesh(out, inst, names=[f"p{k}" for k in range(6)])
    assert rep.passed and len(rep.bodies) == 6
    v, f = read_mesh_arrays(out)
    assert len(f) == sum(len(b[1]) for b in inst.bodies())
    want = sum(trimesh.Trimesh(*b, process=False).volume for b in inst.bodies())
    assert rep.volume == pytest.approx(want, rel=1e-6)


def test_instances_need_one_name_per_body(tmp_path):
    with pytest.raises(InputError, match="2 names for 6 bodies"):
        write_mesh(tmp_path / "p.3mf", _instances(), names=["a", "b"])
    assert not (tmp_path / "p.3mf").exists()
