"""OFF text files (Geomview's format): vertices and triangles, what is wrong named by its
line (:func:`off_arrays`; docs/notes-meshes-io.md). Units and frame are the file's.
"""

from __future__ import annotations

import re

import numpy as np

from .errors import MeshError
from .polygons import polygons_to_triangles

Arrays = tuple[np.ndarray, np.ndarray]

#: Geomview's optional OFF keyword, [ST][C][N][4][n]OFF: 4 adds a homogeneous coordinate to
#: each vertex, n a line with the dimension (not read)
_OFF_KEYWORD = re.compile(rb"((?:ST)?C?N?4?N?)OFF(\d*)", re.IGNORECASE)


def off_keyword(word: bytes) -> tuple[bool, bool, bytes] | None:
    """The OFF keyword ``word`` in any case, or None: (a w coordinate follows each vertex
    (4), a dimension line follows (a lower-case n just before OFF, as Geomview writes it;
    an upper-case N is normals), the first count glued to it ("OFF8", as ModelNet has it))."""
    found = _OFF_KEYWORD.fullmatch(word)
    if found is None:
        return None
    prefix = found[1]
    return b"4" in prefix, prefix.endswith(b"n"), found[2]


#: bytes some tools pad a file's end with (NUL; Ctrl-Z, DOS's end of file): not the data
PADDING = b"\x00\x1a"


def _off_face_like(words: list[bytes]) -> bool:
    """An OFF line that reads as a polygon: a corner count of 3 or more and as many whole
    numbers (an edge line has 2 corners)."""
    if not words[0].isdigit() or int(words[0]) < 3 or len(words) < int(words[0]) + 1:
        return False
    return all(w.isdigit() for w in words[1:int(words[0]) + 1])


def off_arrays(data: bytes, label: str) -> Arrays:
    """Vertices and triangles of an ASCII OFF file, its polygons triangulated in file order
    (`polygons.polygons_to_triangles`: convex ones fanned, concave ones ear-clipped).

    Read here, not by trimesh or meshio: trimesh's OFF reader fails on polygons of mixed
    sizes where one has over four corners and reads a file cut short as the faces it holds;
    meshio reads triangles only. Comments (#) and blank lines are skipped; one vertex or
    face a line, as writers write them; numbers after a vertex's x y z (normals, colours)
    and after a face's corners (its colour) are ignored.

    Raises:
        MeshError: binary OFF, or a line that breaks the format, an index out of range, or
            fewer or more lines than the counts promise (the line and what is wrong).
    """
    rows = [(number, words) for number, line in
            enumerate(data.removeprefix(b"\xef\xbb\xbf").translate(None, PADDING)
                      .splitlines(), start=1)
            if (words := line.split(b"#", 1)[0].split())]

    def shown(words: list[bytes]) -> str:
        return b" ".join(words).decode("latin-1")[:80]

    def bad(number: int, what: str, fix: str = "Export it again (as OFF, PLY or STL)"
            ) -> MeshError:
        return MeshError(f"{label} is not a valid OFF file: line {number} {what}. "
                         f"{fix}.")

    if not rows:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    number, words = rows[0]
    keyword, at = off_keyword(words[0]), 1
    if keyword:
        if words[1:2] == [b"BINARY"]:
            raise bad(number, "says it is a binary OFF, which is not read",
                      "Export it as ASCII OFF, or as PLY or STL")
        if keyword[1]:
            raise bad(number, f"starts with '{shown(words[:1])}' (vertices of any "
                      "dimension), which is not read", "Export it as plain (3D) OFF")
        # the first count glued to the keyword ("OFF8 12 0", as ModelNet's files have it)
        words = [keyword[2], *words[1:]] if keyword[2] else words[1:]
        if not words and len(rows) > 1:  # the counts on the next line, as most write them
            (number, words), at = rows[1], 2
    if len(words) < 2 or not (words[0].isdigit() and words[1].isdigit()):
        raise bad(number, f"should hold the counts of vertices, faces and edges ('8 6 12'), "
                  f"not '{shown(words)}'")
    counts, n_vertices, n_faces = number, int(words[0]), int(words[1])
    held = len(rows) - at
    # lines after the faces are read as trimesh read them, left out (edges some writers
    # list, an "end"), unless they are faces: then the counts leave faces out
    more = sum(1 for _, w in rows[at + n_vertices + n_faces:] if _off_face_like(w))
    if held < n_vertices + n_faces or more:
        how = (f"holds {held:,} lines of them: it was cut short" if not more
               else f"holds {more:,} more face{'s' if more > 1 else ''} after them: the "
               "counts are wrong or the file is damaged")
        raise MeshError(f"{label} is not a whole OFF file: its counts on line {counts} promise "
                        f"{n_vertices:,} vertices and {n_faces:,} faces, one a line, but it "
                        f"{how}. Copy or export it again.")
    rows = rows[:at + n_vertices + n_faces]

    width = 4 if keyword and keyword[0] else 3
    vertex_rows = rows[at:at + n_vertices]
    try:
        vertices = np.array([w[:width] for _, w in vertex_rows], np.float64).reshape(-1, width)
    except ValueError:  # find the line, for the message
        for i, (number, words) in enumerate(vertex_rows, start=1):
            try:
                np.array(words[:width], np.float64).reshape(width)
            except ValueError:
                raise bad(number, f"(vertex {i} of {n_vertices:,}) should start with {width} "
                          f"numbers ({'x y z w' if width == 4 else 'x y z'}), not "
                          f"'{shown(words)}'") from None
        raise
    if width == 4:
        vertices = vertices[:, :3] / vertices[:, 3:]

    face_rows = rows[at + n_vertices:]
    sizes = np.zeros(n_faces, np.int64)
    corners: list[bytes] = []
    for i, (number, words) in enumerate(face_rows):
        size = int(words[0]) if words[0].isdigit() else 0
        where = f"(face {i + 1} of {n_faces:,})"
        if size < 3 or len(words) < size + 1:
            raise bad(number, f"{where} should be a corner count (3 or more) and as many "
                      f"vertex indices, not '{shown(words)}'")
        sizes[i] = size
        corners += words[1:size + 1]
    try:
        flat = np.array(corners, np.int64)
    except (ValueError, OverflowError):  # find the line, for the message
        for i, (number, words) in enumerate(face_rows):
            try:
                np.array(words[1:sizes[i] + 1], np.int64)
            except (ValueError, OverflowError):
                raise bad(number, f"(face {i + 1} of {n_faces:,}) has a corner that is not a "
                          f"vertex index (a whole number): '{shown(words)}'") from None
        raise
    wrong = np.flatnonzero((flat < 0) | (flat >= n_vertices))
    if len(wrong):
        face = int(np.searchsorted(np.cumsum(sizes), wrong[0], side="right"))
        number = face_rows[face][0]
        raise bad(number, f"(face {face + 1} of {n_faces:,}) refers to vertex "
                  f"{flat[wrong[0]]}, but its {n_vertices:,} vertices are numbered 0 to "
                  f"{n_vertices - 1:,}")

    return vertices, polygons_to_triangles(vertices, sizes, flat)
