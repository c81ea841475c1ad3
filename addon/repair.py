"""The safe mesh repairs of Make Manifold: merge by distance, fill holes, recalculate normals.

"Safe": each only adds what a closed surface lacks or joins what coincides; none moves a
vertex further than the merge distance or removes a face with area. Applied to the mesh
datablock (not its modifiers), with Blender's bmesh operators, on the main thread.
"""

from dataclasses import dataclass

import bmesh
import bpy


@dataclass
class Repair:
    """What :func:`make_manifold` changed in one mesh."""

    merged: int  # vertices removed by merging
    holes: int  # faces added to close holes

    def summary(self) -> str:
        return f"merged {self.merged} vertices, filled {self.holes} holes"


def make_manifold(mesh: bpy.types.Mesh, merge_distance: float) -> Repair:
    """Merge vertices closer than ``merge_distance`` (mesh units), fill every hole (any
    number of sides) and turn all faces outward, consistently; the mesh must not be in edit
    mode."""
    bm = bmesh.new()
    try:
        bm.from_mesh(mesh)
        before = len(bm.verts)
        bmesh.ops.remove_doubles(bm, verts=list(bm.verts), dist=merge_distance)
        merged = before - len(bm.verts)
        boundary = [e for e in bm.edges if e.is_boundary]
        filled = bmesh.ops.holes_fill(bm, edges=boundary, sides=0)["faces"] if boundary \
            else []
        bmesh.ops.recalc_face_normals(bm, faces=list(bm.faces))
        bm.to_mesh(mesh)
    finally:
        bm.free()
    mesh.update()
    return Repair(merged=merged, holes=len(filled))
