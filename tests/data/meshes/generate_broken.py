"""Writes the two generated files of broken/ (run from anywhere; the output is committed).

- ``broken/spot_with_holes.obj``: Spot the cow (containers/spot.obj) with five patches of
  faces deleted: an open mesh with five holes, for the "not closed" errors.
- ``broken/vase_thin_wall_shell.stl``: a vase modelled as its 2 mm wall (a revolved profile):
  a closed, valid solid, but as a container its solid is the wall, not the cavity.

Usage: python tests/data/meshes/generate_broken.py
"""

from __future__ import annotations

from pathlib import Path

import manifold3d
import numpy as np
import trimesh

HERE = Path(__file__).resolve().parent
HOLES = 5
#: size of each deleted patch: the faces that touch a vertex this many edges from the seed
HOLE_RINGS = 3


def spot_with_holes() -> tuple[np.ndarray, np.ndarray]:
    """Spot's vertices and faces less HOLES patches far apart: each patch is the faces around
    a seed vertex within HOLE_RINGS rings of edges (a disk), seeds by farthest-point sampling."""
    spot = trimesh.load(HERE / "containers" / "spot.obj", force="mesh", process=False)
    # one vertex per position: the file repeats vertices along its texture seams
    spot = trimesh.Trimesh(spot.vertices, spot.faces, process=False)
    spot.merge_vertices()
    vertices, faces = np.asarray(spot.vertices), np.asarray(spot.faces)
    seeds = [0]
    gap = np.linalg.norm(vertices - vertices[0], axis=1)
    for _ in range(HOLES - 1):
        seeds.append(int(np.argmax(gap)))
        gap = np.minimum(gap, np.linalg.norm(vertices - vertices[seeds[-1]], axis=1))
    neighbours = spot.vertex_neighbors
    ring = set(seeds)
    for _ in range(HOLE_RINGS - 1):
        ring |= {n for v in ring for n in neighbours[v]}
    deleted = np.isin(faces, list(ring)).any(axis=1)
    used, kept = np.unique(faces[~deleted], return_inverse=True)
    return vertices[used], kept.reshape(-1, 3)


def boundary_loops(faces: np.ndarray) -> tuple[int, int]:
    """(open edges, holes): edges used by one face, and the loops they form."""
    edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    unique, counts = np.unique(edges, axis=0, return_counts=True)
    open_edges = unique[counts == 1]
    graph = trimesh.graph.nx.from_edgelist(open_edges.tolist())
    return len(open_edges), trimesh.graph.nx.number_connected_components(graph)


def vase() -> manifold3d.Manifold:
    """A 120 mm vase whose solid is its 2 mm wall and 2 mm base (revolved about z)."""
    z = np.linspace(0.0, 120.0, 25)
    outer = 30.0 + 10.0 * np.sin(z / 120.0 * np.pi) - 8.0 * (z / 120.0) ** 2
    inner = outer - 2.0
    profile = ([(0.0, 0.0)] + list(zip(outer, z, strict=True))
               + list(zip(inner[::-1], z[::-1], strict=True))[:-1] + [(inner[0], 2.0), (0.0, 2.0)])
    section = manifold3d.CrossSection([np.array(profile)])
    return manifold3d.Manifold.revolve(section, 48)


def main() -> None:
    vertices, faces = spot_with_holes()
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    (HERE / "broken" / "spot_with_holes.obj").write_text("\n".join(lines) + "\n")
    open_edges, holes = boundary_loops(faces)
    print(f"spot_with_holes.obj: {len(faces)} faces, {open_edges} open edges, {holes} holes")

    mesh = vase().to_mesh()
    shell = trimesh.Trimesh(np.asarray(mesh.vert_properties)[:, :3], np.asarray(mesh.tri_verts),
                            process=False)
    shell.export(HERE / "broken" / "vase_thin_wall_shell.stl")
    print(f"vase_thin_wall_shell.stl: {len(shell.faces)} faces, watertight "
          f"{shell.is_watertight}, volume {shell.volume:.0f} mm3")


if __name__ == "__main__":
    main()
