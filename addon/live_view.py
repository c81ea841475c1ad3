"""The live view while packing: the objects placed so far as wire spheres in the viewport.

A pack job publishes snapshots (:meth:`worker.Job.publish`: centres, bounding radii and
types, world space, Blender units); the modal runner copies the latest into :data:`VIEW`
on the main thread (:meth:`LiveView.update`) and tags the viewports for redraw. A
``SpaceView3D`` draw handler (POST_VIEW) draws each object as three great circles of its
bounding sphere, coloured by type. The handler is added when a pack starts and removed when
it ends, on every exit path (the runner's ``end``), and on unregister.

Drawing needs a GPU context (not there in background mode, where the handler is added but
never called); everything else is plain numpy.
"""

from __future__ import annotations

import math

import bpy
import numpy as np

#: segments per circle
SEGMENTS = 16
#: at most this many objects are drawn (the latest snapshot's first ones)
MAX_OBJECTS = 4000
#: type colours (RGBA), repeated for more types
COLOURS = ((0.95, 0.55, 0.15, 0.9), (0.95, 0.85, 0.2, 0.9), (0.45, 0.8, 0.3, 0.9),
           (0.35, 0.6, 0.95, 0.9), (0.85, 0.35, 0.6, 0.9), (0.6, 0.45, 0.95, 0.9))


def circle_lines(centres: np.ndarray, radii: np.ndarray, segments: int = SEGMENTS
                 ) -> np.ndarray:
    """(N * 3 * segments * 2, 3) float32 line end points: per sphere, its great circles in
    the xy, xz and yz planes as ``segments`` line segments each."""
    a = np.linspace(0.0, 2.0 * math.pi, segments + 1)
    c, s = np.cos(a), np.sin(a)
    z = np.zeros_like(a)
    rings = np.stack([np.stack([c, s, z], 1), np.stack([c, z, s], 1),
                      np.stack([z, c, s], 1)])  # (3, segments + 1, 3) unit circles
    seg = np.stack([rings[:, :-1], rings[:, 1:]], axis=2).reshape(-1, 3)  # (3*seg*2, 3)
    pts = centres[:, None, :] + radii[:, None, None] * seg[None]
    return np.ascontiguousarray(pts.reshape(-1, 3), np.float32)


class LiveView:
    """The latest snapshot of the running pack and the draw handler showing it."""

    def __init__(self) -> None:
        self.handle = None  # the SpaceView3D draw handler while a pack runs
        self.placed = None  # the latest worker.Placed, main thread only
        self.updates = 0  # snapshots received (tests read it)
        self._batches: list | None = None  # (batch, colour) per type, for `placed`
        self.broken = False  # drawing failed once (no GPU module, a driver): draw nothing

    @property
    def active(self) -> bool:
        return self.handle is not None

    def start(self) -> None:
        """Add the draw handler (once) and forget any earlier snapshot."""
        self.placed, self.updates, self._batches = None, 0, None
        if self.handle is None:
            self.handle = bpy.types.SpaceView3D.draw_handler_add(
                _draw, (), 'WINDOW', 'POST_VIEW')

    def stop(self) -> None:
        """Remove the draw handler and the snapshot (safe to call twice)."""
        handle, self.handle = self.handle, None
        self.placed, self._batches = None, None
        if handle is not None:
            bpy.types.SpaceView3D.draw_handler_remove(handle, 'WINDOW')

    def update(self, placed) -> bool:
        """Take a newer snapshot (a worker.Placed or None); True when it is new."""
        if placed is None or placed is self.placed or not self.active:
            return False
        self.placed, self._batches = placed, None
        self.updates += 1
        return True

    def lines_by_type(self) -> dict[int, np.ndarray]:
        """The current snapshot's circles as line end points (world space), per type."""
        p = self.placed
        if p is None or len(p.types) == 0:
            return {}
        types = np.asarray(p.types)[:MAX_OBJECTS]
        pos = np.asarray(p.positions, np.float64)[:MAX_OBJECTS]
        rad = np.asarray(p.radii, np.float64)[:MAX_OBJECTS]
        return {int(t): circle_lines(pos[types == t], rad[types == t])
                for t in np.unique(types)}

    def draw(self) -> None:
        """Draw the snapshot (called by Blender with a GPU context)."""
        import gpu
        from gpu_extras.batch import batch_for_shader

        if self.placed is None or self.broken:
            return
        shader = gpu.shader.from_builtin('UNIFORM_COLOR')
        if self._batches is None:
            self._batches = [(batch_for_shader(shader, 'LINES', {"pos": lines}),
                              COLOURS[t % len(COLOURS)])
                             for t, lines in self.lines_by_type().items()]
        gpu.state.depth_test_set('LESS_EQUAL')
        gpu.state.blend_set('ALPHA')
        for batch, colour in self._batches:
            shader.uniform_float("color", colour)
            batch.draw(shader)
        gpu.state.blend_set('NONE')
        gpu.state.depth_test_set('NONE')


#: the add-on's one live view (one job at a time)
VIEW = LiveView()


def _draw() -> None:
    try:
        VIEW.draw()
    except Exception as exc:  # noqa: BLE001 - a drawing error must not spam every redraw
        print(f"Jampacked live view off: {type(exc).__name__}: {exc}")
        VIEW.broken = True


def unregister() -> None:
    """Remove the draw handler if a pack was still shown."""
    VIEW.stop()
