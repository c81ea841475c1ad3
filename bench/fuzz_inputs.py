#!/usr/bin/env python3
"""Input fuzzing of jampacked: bad and odd meshes, packing files and CLI arguments.

Usage (with the project's python, see project_env.sh; run it niced on a shared machine):

    # from the project's root, with a python that has the project installed:
    .venv/bin/python ../shared/fuzz/fuzz_inputs.py --n 300 --seed 0 --out fuzz-report.json

    # one case again, files kept under --workdir/case_NNNNN:
    .venv/bin/python ../shared/fuzz/fuzz_inputs.py --seed 0 --only-id 123 --keep --out one.json

Design: the parent process (numpy only) plans every case from (seed, case id) and feeds the
ids one by one to ONE long-lived worker process (which imports jampacked once and warms up
numba). Each case runs in the worker under signal.alarm(limit); the parent also kills the
worker when no answer comes within limit + grace (native code that ignores the alarm), records
a hang and starts a fresh worker. The worker runs under an address-space limit (--mem-gb).

Classes: a = clear project error (JampackedError, or CLI exit != 0 with an 'error:' /
usage message, no traceback); b = accepted, result checked valid; c = BUG other exception /
traceback (also a crashed worker); d = BUG hang beyond the limit; e = BUG accepted but the
result is invalid (NaN, object outside, broken MeshData guarantee, validator verdict wrong);
f = data loss (an input file changed, a pre-existing output destroyed on failure, a
half-written output or a temp file left behind).  h = harness error (our own generator
failed; not a project finding).

Provenance: the company's input-fuzzing harness, copied from ../shared/fuzz/fuzz_inputs.py
(its README there has the first results) into the project by issue 20, so that the suite
(tests/fuzz/test_fuzz.py, a small seeded run) and `make fuzz SEED=S` (N=1000) run it.
Changes since the copy: `--fail-on` (exit status 1 when a case of those classes occurs);
3MF packages name their model part in `_rels/.rels` (the copy's empty relationships made
every 3MF, the good ones too, a package that lib3mf and now jampacked refuse).
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import io
import json
import math
import os
import pathlib
import random
import select
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import time
import traceback
import zipfile

PROJECT_MARK = os.path.join(os.getcwd(), "")  # run from the project root
CLASSES = "abcdefh"
CLASS_NAMES = {
    "a": "clear project error",
    "b": "accepted, valid result",
    "c": "BUG exception/traceback",
    "d": "BUG hang",
    "e": "BUG invalid result accepted",
    "f": "data loss / partial output",
    "h": "harness error",
}

# --------------------------------------------------------------------------------------------
# planning (parent and worker; pure python, deterministic in (seed, id))

# mesh generators: name -> (load expectation, validate expectation)
#   load: accept (valid or safely repairable), reject, either
#   validate: pass, fail, either (validate reads as written: no repair)
MESH_GENS = {
    "good_box": ("accept", "pass"),
    "good_sphere": ("accept", "pass"),
    "scaled_tiny": ("either", "either"),  # 1e-9
    "scaled_huge": ("either", "either"),  # 1e9
    "scaled_extreme": ("either", "either"),  # 1e-300 .. 1e300
    "far_offset": ("either", "either"),
    "inverted": ("accept", "fail"),
    "partial_flip": ("accept", "fail"),
    "dup_faces": ("accept", "fail"),
    "opposite_pair": ("accept", "fail"),
    "degenerate_faces": ("accept", "fail"),
    "unreferenced_verts": ("accept", "pass"),
    "jitter_verts": ("accept", "either"),
    "soup_split": ("accept", "pass"),
    "sliver_body": ("accept", "either"),
    "open": ("reject", "fail"),
    "nonmanifold_edge": ("reject", "fail"),
    "fin": ("reject", "fail"),
    "two_bodies": ("reject", "pass"),
    "nested_bodies": ("reject", "fail"),
    "overlapping_bodies": ("reject", "fail"),
    "self_intersect": ("either", "fail"),
    "nan_coord": ("reject", "fail"),
    "inf_coord": ("reject", "fail"),
    "single_tri": ("reject", "fail"),
    "zero_faces": ("reject", "fail"),
    "soup": ("reject", "fail"),
    "flat": ("reject", "fail"),
    "collapsed": ("reject", "fail"),
    "klein": ("reject", "fail"),
    "bad_index": ("reject", "fail"),
}
# raw-byte generators (files that are damaged as files)
RAW_GENS = [
    "empty", "whitespace", "garbage", "wrong_ext", "no_ext", "upper_ext", "stl_truncated",
    "stl_count_lie", "stl_short", "ascii_stl_garbage", "ply_bad_header", "obj_bad_idx",
    "obj_neg_idx", "obj_weird", "off_bad", "3mf_corrupt", "dir_path", "missing_path",
    "symlink_loop",
]
FORMATS = ["stl", "stl_ascii", "obj", "ply", "ply_ascii", "off", "3mf"]
JSON_NAMES = ["fuzz.json", "cube.stl", "ball.obj", "container.obj"]
PACK_FORMATS = ["stl", "stl_ascii", "obj", "ply"]
NEEDS_INDEXED = {"bad_index", "zero_faces", "unreferenced_verts"}

JSON_MUTATIONS = [
    "delete_key", "weird_leaf", "version", "format", "sha256", "path_outside", "nan_matrix",
    "matrix_shape", "many_placements", "type_index", "rotation", "scale_consistent",
    "translation_far", "truncated", "garbage", "empty", "bom", "toplevel", "deep_nesting",
    "bigint", "meta_fields", "clearance_param", "no_types", "dup_keys", "valid",
]

KIND_WEIGHTS = [
    ("load", 22), ("validate", 14), ("cli_validate", 5), ("pack_api", 10), ("cli_pack", 12),
    ("packing_load", 10), ("cli_info", 8), ("export_api", 9), ("cli_export", 10),
]
LIMITS = {"load": 30, "validate": 45, "cli_validate": 45, "pack_api": 120, "cli_pack": 120,
          "packing_load": 40, "cli_info": 60, "export_api": 120, "cli_export": 120}
HUGE_LIMIT = 300
GRACE = 30


def _wchoice(r: random.Random, pairs):
    total = sum(w for _, w in pairs)
    x = r.uniform(0, total)
    for item, w in pairs:
        x -= w
        if x <= 0:
            return item
    return pairs[-1][0]


def plan_case(seed: int, i: int, huge_every: int) -> dict:
    r = random.Random(f"jampacked-fuzz-{seed}-{i}")
    rseed = r.randrange(2**32)
    if huge_every and i % huge_every == huge_every // 2:
        kind = "load" if (i // huge_every) % 2 == 0 else "validate"
        return {"id": i, "kind": kind, "gen": "huge", "fmt": "stl", "rseed": rseed,
                "limit": HUGE_LIMIT}
    kind = _wchoice(r, KIND_WEIGHTS)
    plan = {"id": i, "kind": kind, "rseed": rseed, "limit": LIMITS[kind]}
    if kind in ("load", "validate", "cli_validate"):
        if r.random() < 0.35:
            plan["gen"] = "raw:" + r.choice(RAW_GENS)
            plan["fmt"] = None
        else:
            gen = r.choice(list(MESH_GENS))
            fmts = [f for f in FORMATS if not (gen in NEEDS_INDEXED and f.startswith("stl"))]
            if kind == "load" and r.random() < 0.8:
                fmts = [f for f in fmts if f != "3mf"]  # the core reads 3MF only with lxml
            plan["gen"] = gen
            plan["fmt"] = r.choice(fmts)
        plan["role"] = r.choice(["object", "object", "container"])
    elif kind in ("pack_api", "cli_pack"):
        plan["gen"] = r.choice(_PACK_GENS_API if kind == "pack_api" else _PACK_GENS_CLI)
        plan["fmt"] = r.choice(PACK_FORMATS)
    elif kind in ("packing_load", "cli_info", "export_api", "cli_export"):
        muts = JSON_MUTATIONS
        if kind in ("export_api", "cli_export"):
            # export is slow: fewer giant files, more option mutations
            muts = [m for m in JSON_MUTATIONS if m != "many_placements"] + ["options"] * 8
        plan["gen"] = r.choice(muts)
    return plan


_PACK_GENS_API = [
    "valid", "container_mesh", "container_bad", "type_bad", "type_repairable", "box_spec",
    "clearance", "shares", "seed", "time_budget", "container_size", "type_scale", "fidelity",
    "names", "no_types", "container_repairable", "type_huge_vs_container", "api_values",
]
_PACK_GENS_CLI = [
    "valid", "clearance", "type_share", "container_size", "type_scale", "time_budget", "seed",
    "mix_tolerance", "fidelity", "output", "preview", "box_spec", "container_bad", "type_bad",
    "type_repairable", "default_badargs", "missing_args",
]


# --------------------------------------------------------------------------------------------
# worker side


def _shown_types(types) -> str:
    """The types argument of a pack case for its description (any value the case passes)."""
    if not isinstance(types, (list, tuple)):
        return repr(types)[:60]
    return str([os.path.basename(t) if isinstance(t, (str, os.PathLike)) else repr(t)[:40]
                for t in types])


class HarnessTimeout(BaseException):
    """Raised by SIGALRM inside the worker (BaseException: project code catching Exception
    must not swallow it)."""


def _alarm(signum, frame):
    raise HarnessTimeout()


def sha(path: str) -> str | None:
    try:
        with open(path, "rb") as fh:
            return hashlib.sha256(fh.read()).hexdigest()
    except OSError:
        return None


def tree_hashes(folder: str) -> dict[str, str | None]:
    out = {}
    for root, _dirs, files in os.walk(folder):
        for name in files:
            p = os.path.join(root, name)
            if os.path.islink(p):
                continue
            out[os.path.relpath(p, folder)] = sha(p)
    return out


class Outcome(Exception):
    """Raised by oracles: the result is invalid (class e) or data was lost (class f)."""

    def __init__(self, cls: str, msg: str):
        super().__init__(msg)
        self.cls = cls


class Worker:
    def __init__(self, args):
        import numpy as np
        import trimesh

        self.np = np
        self.trimesh = trimesh
        self.args = args
        self.work = args.workdir
        os.makedirs(self.work, exist_ok=True)
        # imports of the project
        import jampacked.cli.main as cli_main
        from jampacked.core import api, errors, meshes, packing
        from jampacked.export import assemble, validate
        from jampacked.export import io as eio

        self.cli_main = cli_main
        self.api = api
        self.errors = errors
        self.meshes = meshes
        self.packing = packing
        self.assemble = assemble
        self.validate = validate
        self.eio = eio

    # ----------------------------------------------------------------- warm-up
    def warm_up(self) -> float:
        t = time.perf_counter()
        d = os.path.join(self.work, "warmup")
        os.makedirs(d, exist_ok=True)
        ball = self.trimesh.creation.icosphere(1, radius=4.0)
        p = os.path.join(d, "ball.obj")
        self.write_mesh(p, "obj", ball.vertices, ball.faces)
        pk = self.api.pack("box:24x24x24", [p], time_budget=1.0, fidelity="low",
                           use_cache=False)
        out = os.path.join(d, "real.json")
        self.packing.save_packing(pk, out)
        self.validate.validate_file(p)
        if pk.n:
            with contextlib.suppress(Exception):
                self.assemble.export_packing(out, [os.path.join(d, "w.stl")],
                                             self.assemble.ExportOptions(mode="parts")
                                             if hasattr(self.assemble, "ExportOptions") else None)
        return time.perf_counter() - t

    # ----------------------------------------------------------------- mesh writing
    def write_mesh(self, path: str, fmt: str, v, f) -> None:
        np = self.np
        v = np.asarray(v, np.float64).reshape(-1, 3)
        f = np.asarray(f, np.int64).reshape(-1, 3)
        if fmt == "stl":
            buf = io.BytesIO()
            buf.write(b"fuzz binary stl".ljust(80, b" "))
            buf.write(struct.pack("<I", len(f)))
            rec = np.zeros(len(f), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
            if len(f):
                with np.errstate(all="ignore"):
                    rec["v"] = v[f].astype(np.float32)
            buf.write(rec.tobytes())
            data = buf.getvalue()
        elif fmt == "stl_ascii":
            lines = ["solid fuzz"]
            for tri in (v[f] if len(f) else []):
                lines += ["facet normal 0 0 0", " outer loop"]
                lines += [f"  vertex {a!r} {b!r} {c!r}" for a, b, c in tri.tolist()]
                lines += [" endloop", "endfacet"]
            lines.append("endsolid fuzz")
            data = ("\n".join(lines) + "\n").encode()
        elif fmt == "obj":
            lines = [f"v {a!r} {b!r} {c!r}" for a, b, c in v.tolist()]
            lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in f.tolist()]
            data = ("\n".join(lines) + "\n").encode()
        elif fmt == "ply_ascii":
            head = ["ply", "format ascii 1.0", f"element vertex {len(v)}", "property float x",
                    "property float y", "property float z", f"element face {len(f)}",
                    "property list uchar int vertex_indices", "end_header"]
            lines = head + [f"{a!r} {b!r} {c!r}" for a, b, c in v.tolist()]
            lines += [f"3 {a} {b} {c}" for a, b, c in f.tolist()]
            data = ("\n".join(lines) + "\n").encode()
        elif fmt == "ply":
            head = ("ply\nformat binary_little_endian 1.0\n"
                    f"element vertex {len(v)}\nproperty double x\nproperty double y\n"
                    f"property double z\nelement face {len(f)}\n"
                    "property list uchar int vertex_indices\nend_header\n").encode()
            fr = np.zeros(len(f), dtype=[("c", "u1"), ("i", "<i4", 3)])
            fr["c"] = 3
            if len(f):
                fr["i"] = f
            data = head + v.astype("<f8").tobytes() + fr.tobytes()
        elif fmt == "off":
            lines = ["OFF", f"{len(v)} {len(f)} 0"]
            lines += [f"{a!r} {b!r} {c!r}" for a, b, c in v.tolist()]
            lines += [f"3 {a} {b} {c}" for a, b, c in f.tolist()]
            data = ("\n".join(lines) + "\n").encode()
        elif fmt == "3mf":
            data = self.make_3mf(v, f)
        else:
            raise ValueError(fmt)
        with open(path, "wb") as fh:
            fh.write(data)

    def make_3mf(self, v, f, model_xml: str | None = None, name="3D/3dmodel.model") -> bytes:
        if model_xml is None:
            parts = ['<?xml version="1.0" encoding="UTF-8"?>\n<model unit="millimeter" '
                     'xmlns="http://schemas.microsoft.com/3dmanufacturing/core/2015/02">'
                     '<resources><object id="1" type="model"><mesh><vertices>']
            parts += [f'<vertex x="{a!r}" y="{b!r}" z="{c!r}"/>' for a, b, c in v.tolist()]
            parts.append("</vertices><triangles>")
            parts += [f'<triangle v1="{a}" v2="{b}" v3="{c}"/>' for a, b, c in f.tolist()]
            parts.append('</triangles></mesh></object></resources><build><item objectid="1"/>'
                         "</build></model>")
            model_xml = "".join(parts)
        buf = io.BytesIO()
        with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
            z.writestr("[Content_Types].xml", '<?xml version="1.0"?><Types xmlns="http://'
                       'schemas.openxmlformats.org/package/2006/content-types"/>')
            # the package's one relationship to its model part (3MF core spec; the reader
            # refuses a package without it, as lib3mf does)
            z.writestr("_rels/.rels", '<?xml version="1.0"?><Relationships xmlns="http://'
                       'schemas.openxmlformats.org/package/2006/relationships"><Relationship '
                       'Target="/3D/3dmodel.model" Id="rel0" Type="http://schemas.microsoft.'
                       'com/3dmanufacturing/2013/01/3dmodel"/></Relationships>')
            if name:
                z.writestr(name, model_xml)
        return buf.getvalue()

    # ----------------------------------------------------------------- geometry generators
    def base_shape(self, rng, size=10.0):
        tm = self.trimesh
        if rng.random() < 0.5:
            m = tm.creation.box(extents=(size, size * rng.uniform(0.6, 1.4), size * 0.8))
        else:
            m = tm.creation.icosphere(1, radius=size / 2)
        return self.np.array(m.vertices, float), self.np.array(m.faces, int)

    def geometry(self, gen: str, rng, size=10.0):
        """(vertices, faces, description) for a mesh generator name."""
        np, tm = self.np, self.trimesh
        v, f = self.base_shape(rng, size)
        d = gen
        if gen == "good_box":
            m = tm.creation.box(extents=(size, size, size))
            v, f = np.array(m.vertices), np.array(m.faces)
        elif gen == "good_sphere":
            m = tm.creation.icosphere(2, radius=size / 2)
            v, f = np.array(m.vertices), np.array(m.faces)
        elif gen == "scaled_tiny":
            v = v * 1e-9
            d += " x1e-9"
        elif gen == "scaled_huge":
            v = v * 1e9
            d += " x1e9"
        elif gen == "scaled_extreme":
            s = float(rng.choice([1e-300, 1e-200, 1e-30, 1e30, 1e200, 1e300]))
            v = v * s
            d += f" x{s:g}"
        elif gen == "far_offset":
            off = float(rng.choice([1e6, 1e9, 1e12, -1e15]))
            v = v + off
            d += f" +{off:g}"
        elif gen == "inverted":
            f = f[:, ::-1]
        elif gen == "partial_flip":
            k = rng.random(len(f)) < 0.2
            k[0] = True
            f = f.copy()
            f[k] = f[k][:, ::-1]
        elif gen == "dup_faces":
            k = rng.integers(0, len(f), size=int(rng.integers(1, 6)))
            f = np.concatenate([f, f[k]])
        elif gen == "opposite_pair":
            k = rng.integers(0, len(f), size=int(rng.integers(1, 4)))
            # a zero-volume pair of extra faces on existing vertices
            f = np.concatenate([f, f[k][:, [0, 2, 1]], f[k]])
        elif gen == "degenerate_faces":
            k = rng.integers(0, len(f), size=int(rng.integers(1, 6)))
            extra = f[k].copy()
            extra[:, 2] = extra[:, 1]
            f = np.concatenate([f, extra])
        elif gen == "unreferenced_verts":
            v = np.concatenate([v, rng.normal(size=(int(rng.integers(1, 50)), 3)) * 100])
        elif gen == "jitter_verts":
            v = v[f].reshape(-1, 3)
            f = np.arange(len(v)).reshape(-1, 3)
            v = v + rng.normal(size=v.shape) * size * 1e-12
        elif gen == "soup_split":
            v = v[f].reshape(-1, 3)
            f = np.arange(len(v)).reshape(-1, 3)
        elif gen == "sliver_body":
            tet = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float) * size * 1e-4
            tet += size * 3
            tf = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]) + len(v)
            v, f = np.concatenate([v, tet]), np.concatenate([f, tf])
        elif gen == "open":
            k = int(rng.integers(1, min(6, len(f) - 1)))
            f = np.delete(f, rng.choice(len(f), k, replace=False), axis=0)
            d += f" ({k} faces removed)"
        elif gen == "nonmanifold_edge":
            m1 = tm.creation.box(extents=(size, size, size))
            m2 = m1.copy()
            m2.apply_translation((size, size, 0))  # shares one edge with m1
            m = tm.util.concatenate([m1, m2])
            v, f = np.array(m.vertices), np.array(m.faces)
            d += " (two boxes sharing an edge)"
        elif gen == "fin":
            a, b = f[0, 0], f[0, 1]
            v = np.concatenate([v, [v[a] + (v[b] - v[a]) * 0.5 + size]])
            f = np.concatenate([f, [[a, b, len(v) - 1]]])
        elif gen == "two_bodies":
            v2 = v + size * 2
            f = np.concatenate([f, f + len(v)])
            v = np.concatenate([v, v2])
        elif gen == "nested_bodies":
            f = np.concatenate([f, f + len(v)])
            v = np.concatenate([v, v * 0.4])
        elif gen == "overlapping_bodies":
            f = np.concatenate([f, f + len(v)])
            v = np.concatenate([v, v + size * 0.3])
        elif gen == "self_intersect":
            m = tm.creation.box(extents=(size, size, size))
            v, f = np.array(m.vertices), np.array(m.faces)
            top = np.flatnonzero(v[:, 2] > 0)[0]
            v[top, 2] = -2.0 * size  # pushed through the bottom face
            d += " (a box corner pushed through the opposite face)"
        elif gen == "nan_coord":
            v = v.copy()
            v[int(rng.integers(len(v))), int(rng.integers(3))] = np.nan
        elif gen == "inf_coord":
            v = v.copy()
            v[int(rng.integers(len(v))), int(rng.integers(3))] = rng.choice([np.inf, -np.inf])
        elif gen == "single_tri":
            v = np.array([[0, 0, 0], [size, 0, 0], [0, size, 0]], float)
            f = np.array([[0, 1, 2]])
        elif gen == "zero_faces":
            f = np.zeros((0, 3), int)
        elif gen == "soup":
            n = int(rng.integers(1, 200))
            v = rng.normal(size=(3 * n, 3)) * size
            f = np.arange(3 * n).reshape(-1, 3)
            if rng.random() < 0.5:  # shared vertices: random indexing into few points
                v = rng.normal(size=(max(4, n // 3), 3)) * size
                f = rng.integers(0, len(v), size=(n, 3))
            d += f" ({n} random triangles)"
        elif gen == "flat":
            v = v.copy()
            v[:, 2] = 0.0
        elif gen == "collapsed":
            v = np.zeros_like(v) + 1.5
        elif gen == "klein":
            v, f = self.klein(rng, size)
        elif gen == "bad_index":
            f = f.copy()
            f[int(rng.integers(len(f))), int(rng.integers(3))] = int(
                rng.choice([len(v), len(v) + 7, 10**6]))
        elif gen == "huge":
            m = tm.creation.icosphere(8, radius=size)
            v, f = np.array(m.vertices), np.array(m.faces)
            d += f" ({len(f)} faces)"
        else:
            raise ValueError(gen)
        return v, f, d

    def klein(self, rng, size):
        """A closed, edge-manifold, non-orientable mesh (figure-8 Klein bottle immersion)."""
        np = self.np
        nu, nv = 16, 8
        verts = []
        for i in range(nu):
            for j in range(nv):
                u = 2 * np.pi * i / nu
                w = 2 * np.pi * j / nv
                r = 3.0
                x = (r + np.cos(u / 2) * np.sin(w) - np.sin(u / 2) * np.sin(2 * w)) * np.cos(u)
                y = (r + np.cos(u / 2) * np.sin(w) - np.sin(u / 2) * np.sin(2 * w)) * np.sin(u)
                z = np.sin(u / 2) * np.sin(w) + np.cos(u / 2) * np.sin(2 * w)
                verts.append((x, y, z))
        v = np.array(verts) * size / 8

        def idx(i, j):
            if i == nu:  # glue with a flip: (nu, j) ~ (0, -j)
                return (0 * nv) + ((-j) % nv)
            return i * nv + (j % nv)

        faces = []
        for i in range(nu):
            for j in range(nv):
                a, b, c, dd = idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)
                faces += [(a, b, c), (a, c, dd)]
        return v, np.array(faces)

    # ----------------------------------------------------------------- raw generators
    def raw_file(self, gen: str, rng, folder: str) -> tuple[str, str]:
        """Write a damaged file; returns (path, description)."""
        np = self.np
        v, f = self.base_shape(rng)
        good = io.BytesIO()

        def valid_bytes(fmt):
            p = os.path.join(folder, "tmp_valid." + fmt.replace("_ascii", ""))
            self.write_mesh(p, fmt, v, f)
            with open(p, "rb") as fh:
                data = fh.read()
            os.unlink(p)
            return data

        del good
        name, data, desc = None, b"", gen
        if gen == "empty":
            name = "empty." + str(rng.choice(["stl", "obj", "ply", "off", "3mf"]))
        elif gen == "whitespace":
            name = "blank." + str(rng.choice(["stl", "obj", "ply"]))
            data = b" \n\t\r\n" * int(rng.integers(1, 100))
        elif gen == "garbage":
            ext = str(rng.choice(["stl", "obj", "ply", "off", "3mf", "glb", "gltf", "dae",
                                  "vtk", "xyz", "msh"]))
            name = "garbage." + ext
            data = rng.integers(0, 256, size=int(rng.integers(1, 5000)), dtype=np.uint8).tobytes()
            if rng.random() < 0.3:
                data = b"solid " + data  # looks like ASCII STL
            desc += f" .{ext} {len(data)} bytes"
        elif gen == "wrong_ext":
            src, ext = [("obj", "stl"), ("stl", "obj"), ("ply", "off"), ("obj", "ply"),
                        ("stl", "txt"), ("off", "obj"), ("stl_ascii", "ply")][
                int(rng.integers(7))]
            name = f"wrong.{ext}"
            data = valid_bytes(src)
            desc += f" ({src} content named .{ext})"
        elif gen == "no_ext":
            name = "meshfile"
            data = valid_bytes(str(rng.choice(["stl", "obj"])))
        elif gen == "upper_ext":
            fmt = str(rng.choice(["stl", "obj", "ply"]))
            name = "UPPER." + fmt.upper()
            data = valid_bytes(fmt)
        elif gen == "stl_truncated":
            data = valid_bytes("stl")
            cut = int(rng.integers(85, len(data) - 1))
            data = data[:cut]
            name = "truncated.stl"
            desc += f" (cut at {cut} of {len(valid_bytes('stl'))} bytes)"
        elif gen == "stl_count_lie":
            data = bytearray(valid_bytes("stl"))
            n = int(rng.choice([0, 1, 2**31 - 1, 2**32 - 1, 10**6]))
            data[80:84] = struct.pack("<I", n)
            data = bytes(data)
            name = "countlie.stl"
            desc += f" (header says {n} faces)"
        elif gen == "stl_short":
            data = valid_bytes("stl")[: int(rng.integers(1, 84))]
            name = "short.stl"
        elif gen == "ascii_stl_garbage":
            lines = valid_bytes("stl_ascii").decode().splitlines()
            for _ in range(int(rng.integers(1, 6))):
                k = int(rng.integers(len(lines)))
                op = int(rng.integers(5))
                if op == 0:
                    del lines[k]
                elif op == 1:
                    lines[k] = "  vertex one two three"
                elif op == 2:
                    lines[k] = "  vertex nan inf -inf"
                elif op == 3:
                    lines.insert(k, "garbage " * int(rng.integers(1, 20)))
                else:
                    lines[k] = lines[k] + " 1e999"
            name = "garbage_ascii.stl"
            data = ("\n".join(lines) + "\n").encode()
        elif gen == "ply_bad_header":
            head_variants = [
                lambda nv, nf: f"ply\nformat ascii 1.0\nelement vertex {nv + 50}\n",
                lambda nv, nf: f"ply\nformat ascii 1.0\nelement vertex -{nv}\n",
                lambda nv, nf: "ply\nformat ascii 1.0\nelement vertex many\n",
                lambda nv, nf: f"ply\nformat bogus 9.9\nelement vertex {nv}\n",
                lambda nv, nf: f"ply\nformat binary_little_endian 1.0\nelement vertex {nv}\n",
                lambda nv, nf: f"ply\nformat ascii 1.0\nelement vertex {10**12}\n",
                lambda nv, nf: f"plx\nformat ascii 1.0\nelement vertex {nv}\n",
            ]
            k = int(rng.integers(len(head_variants)))
            head = head_variants[k](len(v), len(f))
            props = "property float x\nproperty float y\nproperty float z\n"
            fprop = f"element face {len(f)}\nproperty list uchar int vertex_indices\n"
            end = "end_header\n" if rng.random() < 0.8 else ""
            body = "".join(f"{a} {b} {c}\n" for a, b, c in v.tolist())
            body += "".join(f"3 {a} {b} {c}\n" for a, b, c in f.tolist())
            name = "badheader.ply"
            data = (head + props + fprop + end + body).encode()
            desc += f" (variant {k}{', no end_header' if not end else ''})"
        elif gen == "obj_bad_idx":
            bad = str(rng.choice(["0", str(len(v) + 1), "999999999", "-999", "1.5", "a",
                                  "99999999999999999999999"]))
            lines = [f"v {a} {b} {c}" for a, b, c in v.tolist()]
            fl = [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in f.tolist()]
            k = int(rng.integers(len(fl)))
            parts = fl[k].split()
            parts[1 + int(rng.integers(3))] = bad
            fl[k] = " ".join(parts)
            name = "badidx.obj"
            data = ("\n".join(lines + fl) + "\n").encode()
            desc += f" (index {bad!r} on face line {k + 1})"
        elif gen == "obj_neg_idx":
            # negative (relative) indices: valid OBJ when in range
            lines = []
            for tri in f.tolist():
                for vi in tri:
                    x, y, z = v[vi]
                    lines.append(f"v {x} {y} {z}")
                lines.append("f -3 -2 -1")
            if rng.random() < 0.4:
                lines[-1] = "f -3 -2 -99"  # out of range
                desc += " (last face -99, out of range)"
            name = "negidx.obj"
            data = ("\n".join(lines) + "\n").encode()
        elif gen == "obj_weird":
            lines = [f"v {a} {b} {c}" for a, b, c in v.tolist()]
            fl = [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in f.tolist()]
            op = int(rng.integers(7))
            if op == 0:
                fl.append("f 1 2")  # two-corner face
                desc += " (face with 2 corners)"
            elif op == 1:
                fl.append("f 1 2 2 3")  # polygon listing a vertex twice
                desc += " (quad listing a vertex twice)"
            elif op == 2:
                fl = [s + " # comment" for s in fl]
                desc += " (comments on face lines)"
            elif op == 3:
                lines[0] = "v 1 2"
                desc += " (vertex with 2 coordinates)"
            elif op == 4:
                lines = [s + " 0.5 0.5 0.5" for s in lines]
                desc += " (vertex colours)"
            elif op == 5:
                fl = [" ".join(p + "//1" if i else p for i, p in enumerate(s.split()))
                      for s in fl]
                desc += " (f a//n with missing normals)"
            else:
                lines.insert(0, "mtllib missing.mtl\nusemtl nope\no thing\ng group\ns 1")
                desc += " (missing mtllib)"
            name = "weird.obj"
            data = ("\n".join(lines + fl) + "\n").encode()
        elif gen == "off_bad":
            op = int(rng.integers(3))
            counts = [f"{len(v) + 5} {len(f)} 0", f"{len(v)} {len(f) + 5} 0", "x y z"][op]
            body = "".join(f"{a} {b} {c}\n" for a, b, c in v.tolist())
            body += "".join(f"3 {a} {b} {c}\n" for a, b, c in f.tolist())
            name = "bad.off"
            data = f"OFF\n{counts}\n{body}".encode()
            desc += f" (counts line {counts!r})"
        elif gen == "3mf_corrupt":
            op = int(rng.integers(9))
            name = "corrupt.3mf"
            good3 = self.make_3mf(v, f)
            if op == 0:
                data = good3[: int(rng.integers(10, len(good3) - 10))]
                desc += " (truncated zip)"
            elif op == 1:
                data = self.make_3mf(v, f, model_xml="<model/>", name="other.txt")
                desc += " (zip without a .model file)"
            elif op == 2:
                data = self.make_3mf(v, f, model_xml="<model><resources><object id='1'>")
                desc += " (model: unclosed XML)"
            elif op == 3:
                xml = ('<model><resources><object id="1"><mesh><vertices><vertex x="1"/>'
                       '<vertex x="0" y="0" z="0"/><vertex x="1" y="1" z="1"/></vertices>'
                       '<triangles><triangle v1="0" v2="1" v3="2"/></triangles></mesh>'
                       '</object></resources><build><item objectid="1"/></build></model>')
                data = self.make_3mf(v, f, model_xml=xml)
                desc += " (vertex without y/z attributes)"
            elif op == 4:
                # flip bytes inside the deflated model stream
                b = bytearray(good3)
                start = b.find(b"3D/3dmodel.model") + 16
                for _ in range(8):
                    k = int(rng.integers(start, min(len(b) - 30, start + 400)))
                    b[k] ^= 0xFF
                data = bytes(b)
                desc += " (bit flips in the compressed model)"
            elif op == 5:
                xml = ('<model><resources><object id="1"><components>'
                       '<component objectid="1"/></components></object></resources>'
                       '<build><item objectid="1"/></build></model>')
                data = self.make_3mf(v, f, model_xml=xml)
                desc += " (component referencing itself)"
            elif op == 6:
                xml = self.make_3mf_xml(v, f).replace('<item objectid="1"/>',
                                                      '<item objectid="1" transform="1 2 3"/>')
                data = self.make_3mf(v, f, model_xml=xml)
                desc += " (transform with 3 numbers)"
            elif op == 7:
                xml = self.make_3mf_xml(v, f).replace(
                    '<item objectid="1"/>',
                    '<item objectid="1" transform="nan 0 0 0 1 0 0 0 1 0 0 0"/>')
                data = self.make_3mf(v, f, model_xml=xml)
                desc += " (NaN in the build transform)"
            else:
                xml = self.make_3mf_xml(v, f).replace('v1="0"', 'v1="-5"', 1)
                data = self.make_3mf(v, f, model_xml=xml)
                desc += " (negative triangle index)"
        elif gen == "dir_path":
            p = os.path.join(folder, "adir.stl")
            os.makedirs(p, exist_ok=True)
            return p, desc
        elif gen == "missing_path":
            return os.path.join(folder, "does_not_exist.stl"), desc
        elif gen == "symlink_loop":
            p = os.path.join(folder, "loop.stl")
            with contextlib.suppress(OSError):
                os.symlink(p, p)
            return p, desc
        else:
            raise ValueError(gen)
        p = os.path.join(folder, name)
        with open(p, "wb") as fh:
            fh.write(data)
        return p, desc

    def make_3mf_xml(self, v, f) -> str:
        parts = ['<?xml version="1.0" encoding="UTF-8"?>\n<model unit="millimeter" '
                 'xmlns="http://schemas.microsoft.com/3dmanufacturing/core/2015/02">'
                 '<resources><object id="1" type="model"><mesh><vertices>']
        parts += [f'<vertex x="{a!r}" y="{b!r}" z="{c!r}"/>' for a, b, c in v.tolist()]
        parts.append("</vertices><triangles>")
        parts += [f'<triangle v1="{a}" v2="{b}" v3="{c}"/>' for a, b, c in f.tolist()]
        parts.append('</triangles></mesh></object></resources><build><item objectid="1"/>'
                     "</build></model>")
        return "".join(parts)

    def mesh_file(self, gen: str, fmt: str | None, rng, folder: str, size=10.0,
                  stem="mesh") -> tuple[str, str, str, str]:
        """(path, description, load expectation, validate expectation)."""
        if gen.startswith("raw:"):
            raw = gen[4:]
            p, desc = self.raw_file(raw, rng, folder)
            if raw == "upper_ext" or (raw == "obj_neg_idx" and "out of range" not in desc):
                return p, desc, "accept", "pass"  # valid files
            if raw in ("wrong_ext", "no_ext", "obj_neg_idx", "obj_weird", "ascii_stl_garbage",
                       "ply_bad_header", "off_bad", "3mf_corrupt", "stl_count_lie"):
                return p, desc, "either", "either"
            return p, desc, "reject", "fail"
        v, f, desc = self.geometry(gen, rng, size)
        ext = {"stl_ascii": "stl", "ply_ascii": "ply"}.get(fmt, fmt)
        p = os.path.join(folder, f"{stem}.{ext}")
        self.write_mesh(p, fmt, v, f)
        load_exp, val_exp = MESH_GENS.get(gen, ("accept", "pass"))
        if fmt in ("stl", "stl_ascii", "ply") and gen in ("scaled_extreme", "far_offset"):
            val_exp = "either"  # float32 formats
        return p, f"{desc} as {fmt}", load_exp, val_exp

    # ----------------------------------------------------------------- oracles
    def check_meshdata(self, md) -> None:
        np = self.np
        v, f = md.vertices, md.faces
        if not np.all(np.isfinite(v)):
            raise Outcome("e", "MeshData has non-finite vertices")
        if len(f) == 0 or f.min() < 0 or f.max() >= len(v):
            raise Outcome("e", "MeshData faces out of range / empty")
        if not (math.isfinite(md.volume) and md.volume > 0):
            raise Outcome("e", f"MeshData volume {md.volume}")
        n = len(v)
        e = f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
        und = np.sort(e, axis=1)
        _, cnt = np.unique(und[:, 0] * n + und[:, 1], return_counts=True)
        if np.any(cnt != 2):
            raise Outcome("e", f"MeshData not closed/manifold: {int(np.sum(cnt != 2))} edges "
                               "not used twice")
        _, dc = np.unique(e[:, 0] * n + e[:, 1], return_counts=True)
        if np.any(dc != 1):
            raise Outcome("e", "MeshData winding inconsistent")
        tri = v[f] - v.mean(axis=0)
        vol = float(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6)
        if not vol > 0 or abs(vol - md.volume) > 1e-6 * abs(vol) + 1e-300:
            raise Outcome("e", f"MeshData volume {md.volume} but faces give {vol}")

    def check_packing(self, pk, container_src, types_src, clearance=0.0) -> str:
        """Independent checks of a pack() result; returns a note."""
        np = self.np
        import manifold3d as m3

        for name in ("rotations", "translations", "scales", "frame_from_file"):
            if not np.all(np.isfinite(getattr(pk, name))):
                raise Outcome("e", f"packing.{name} holds NaN/inf")
        if not math.isfinite(pk.container_volume) or pk.container_volume <= 0:
            raise Outcome("e", f"container_volume {pk.container_volume}")
        cert = pk.certificate or {}
        if pk.n and cert.get("certified") is not True:
            raise Outcome("e", f"returned packing not certified: {cert.get('certified')}")
        # save -> load round trip (strict JSON)
        tmpdir = os.path.dirname(types_src[0]) if types_src and isinstance(
            types_src[0], str) else self.work
        out = os.path.join(tmpdir, "roundtrip.json")
        self.packing.save_packing(pk, out)
        with open(out) as fh:
            text = fh.read()
        json.loads(text, parse_constant=lambda c: (_ for _ in ()).throw(
            Outcome("e", f"saved packing JSON holds {c}")))
        back = self.packing.load_packing(out)
        if back.n != pk.n:
            raise Outcome("e", "round trip changed the object count")
        if pk.n == 0:
            return "0 objects"
        # container solid in the container frame
        cm = self.packing.container_mesh(pk)
        cv = cm.vertices @ pk.frame_from_file[:3, :3].T + pk.frame_from_file[:3, 3]
        cont = m3.Manifold(m3.Mesh64(vert_properties=np.ascontiguousarray(cv, np.float64),
                                     tri_verts=np.ascontiguousarray(cm.faces, np.uint32)))
        mats = pk.matrices()
        solids = []
        lo, hi = [], []
        cache = {}
        for i, t in enumerate(pk.type_index):
            rec = pk.types[t]
            if t not in cache:
                cache[t] = self.meshes.load_mesh(rec.path) if rec.path else None
            md = cache[t]
            if md is None:
                return "types without paths: not checked"
            m = mats[i] @ rec.local_from_file
            v = md.vertices @ m[:3, :3].T + m[:3, 3]
            if not np.all(np.isfinite(v)):
                raise Outcome("e", f"object {i} has non-finite vertices")
            s = m3.Manifold(m3.Mesh64(vert_properties=np.ascontiguousarray(v),
                                      tri_verts=np.ascontiguousarray(md.faces, np.uint32)))
            vol = s.volume()
            outside = (s - cont).volume()
            if outside > 1e-3 * vol:
                raise Outcome("e", f"object {i} ({rec.name}) is {outside / vol:.2%} outside "
                                   "the container")
            solids.append((s, vol))
            lo.append(v.min(axis=0))
            hi.append(v.max(axis=0))
        lo, hi = np.array(lo), np.array(hi)
        checked = 0
        for i in range(len(solids)):
            near = np.flatnonzero(np.all(lo[i + 1:] <= hi[i], axis=1)
                                  & np.all(hi[i + 1:] >= lo[i], axis=1)) + i + 1
            for j in near[:50]:
                checked += 1
                ov = (solids[i][0] ^ solids[j][0]).volume()
                if ov > 1e-3 * min(solids[i][1], solids[j][1]):
                    raise Outcome("e", f"objects {i} and {j} overlap by "
                                       f"{ov / min(solids[i][1], solids[j][1]):.2%}")
        return f"{pk.n} objects inside, {checked} near pairs disjoint"

    def check_outputs(self, paths, parts_expected: int | None = None) -> str:
        """Written files validate and hold finite numbers; in parts mode (one file, no
        split) one body per placement."""
        np = self.np
        notes = []
        for p in paths:
            if not os.path.isfile(p):
                raise Outcome("e", f"reported output {p} missing")
            rep = self.validate.validate_file(p, check_manifold3d=False)
            if not rep.passed:
                raise Outcome("e", f"output {os.path.basename(p)} fails validation: "
                                   f"{rep.summary()}")
            if parts_expected is not None and len(rep.bodies) != parts_expected:
                raise Outcome("e", f"parts export {os.path.basename(p)} holds "
                                   f"{len(rep.bodies)} bodies for {parts_expected} placements "
                                   "(objects silently dropped or merged)")
            v, _ = self.eio.read_mesh_arrays(p)
            if not np.all(np.isfinite(v)):
                raise Outcome("e", f"output {p} holds NaN/inf")
            notes.append(f"{os.path.basename(p)} ok")
        return ", ".join(notes)

    # ----------------------------------------------------------------- packing JSON base
    def base_packing(self, folder: str, rng, mesh_container: bool = False):
        """A valid, hand-made packing JSON (with its mesh files) in folder; returns
        (json path, doc, type mesh paths)."""
        np, tm = self.np, self.trimesh
        cube = tm.creation.box(extents=(6, 6, 6))
        tpath = os.path.join(folder, "cube.stl")
        self.write_mesh(tpath, "stl", cube.vertices, cube.faces)
        ball = tm.creation.icosphere(1, radius=3.0)
        bpath = os.path.join(folder, "ball.obj")
        self.write_mesh(bpath, "obj", ball.vertices, ball.faces)
        if mesh_container:
            box = tm.creation.box(extents=(40, 40, 40))
            cpath = os.path.join(folder, "container.obj")
            self.write_mesh(cpath, "obj", box.vertices, box.faces)
            container = {"path": "container.obj", "sha256": sha(cpath)}
        else:
            container = {"path": "box:40x40x40", "sha256": None}
        container.update(frame_from_file=np.eye(4).tolist(), volume=64000.0)
        types = []
        for name, p in (("cube", tpath), ("ball", bpath)):
            md = self.meshes.load_mesh(p)
            lff = np.eye(4)
            lff[:3, 3] = -md.centroid
            types.append({"name": name, "path": os.path.basename(p), "sha256": sha(p),
                          "share": 0.5, "local_from_file": lff.tolist(),
                          "volume": float(md.volume)})
        placements = []
        k = 0
        for x in (-10, 4):
            for y in (-10, 4):
                for z in (-10, 4):
                    q = rng.normal(size=4)
                    q /= np.linalg.norm(q)
                    if q[0] < 0:
                        q = -q
                    placements.append(self.placement(k % 2, q, [x + 3, y + 3, z + 3], 1.0))
                    k += 1
        doc = {
            "format": "jampacked.packing", "version": 1, "container": container,
            "types": types, "placements": placements,
            "params": {"clearance": 0.0, "fidelity": "low", "fidelity_detail": {
                "spheres": 8, "grid_cells": 16, "surface_points": 100, "container_cells": 2.0,
                "reasons": ["fuzz"]}, "stopped": None, "warnings": [],
                "attempts": [{"count": 8, "density": 0.05, "seconds": 0.1}],
                "repair": {"rounds": 0, "moved": 0, "removed": 0}},
            "seed": 0,
            "metrics": {"density": 0.05, "tvd": 0.0, "nni_mean": 1.0, "nni_per_type": [1.0, 1.0],
                        "after_phase1": {"count": 8, "density": 0.05}},
            "timings": {"load": 0.1, "total": 1.0},
            "certificate": {"certified": True, "worst_overlap": 0.0, "worst_outside": 0.0,
                            "tol": 1e-6, "clearance": 0.0, "pairs_checked": 10,
                            "walls_checked": 8},
        }
        return doc, [tpath, bpath]

    def placement(self, t, q, tr, s):
        np = self.np
        try:
            with np.errstate(all="ignore"):
                m = self.packing.placement_matrices(np.array([q], float), np.array([tr], float),
                                                    np.array([s], float))[0]
        except Exception:  # noqa: BLE001 - a quaternion with no rotation: identity matrix
            m = np.eye(4)
            m[:3, 3] = tr
        return {"type": int(t), "matrix": m.tolist(), "rotation": [float(x) for x in q],
                "translation": [float(x) for x in tr], "scale": float(s)}

    def mutate_doc(self, doc, mut: str, rng, folder: str) -> tuple[str | None, str]:
        """Mutate doc in place; returns (raw text override or None, description)."""
        np = self.np
        d = mut
        raw = None

        def paths(obj, pre=()):
            out = [pre]
            if isinstance(obj, dict):
                for k, val in obj.items():
                    out += paths(val, pre + (k,))
            elif isinstance(obj, list):
                for k, val in enumerate(obj[:3]):
                    out += paths(val, pre + (k,))
            return out

        def get(p):
            o = doc
            for k in p:
                o = o[k]
            return o

        def put(p, val):
            get(p[:-1])[p[-1]] = val

        weird = ["__NAN__", "__INF__", "__BIGFLOAT__", "__BIGINT__", None, "", "abc", -1, 0,
                 True, [], {}, [1, 2], {"x": 1}, 1.5, -1e308]
        if mut == "delete_key":
            cands = [p for p in paths(doc) if p and isinstance(p[-1], str)]
            p = cands[int(rng.integers(len(cands)))]
            del get(p[:-1])[p[-1]]
            d += f" {'.'.join(map(str, p))}"
        elif mut == "weird_leaf":
            cands = [p for p in paths(doc) if p]
            p = cands[int(rng.integers(len(cands)))]
            val = weird[int(rng.integers(len(weird)))]
            put(p, val)
            d += f" {'.'.join(map(str, p))} = {val!r}"
        elif mut == "version":
            val = [0, 2, 99, "1", 1.0, -1, None, "__BIGINT__", True][int(rng.integers(9))]
            doc["version"] = val
            d += f" = {val!r}"
        elif mut == "format":
            if rng.random() < 0.5:
                del doc["format"]
                d += " (missing)"
            else:
                doc["format"] = "jampacked.validation"
                d += " (= jampacked.validation)"
        elif mut == "sha256":
            t = int(rng.integers(len(doc["types"])))
            val = ["0" * 64, "nothex", 123, "", doc["types"][t]["sha256"].upper()][
                int(rng.integers(5))]
            doc["types"][t]["sha256"] = val
            d += f" types[{t}].sha256 = {val!r}"
        elif mut == "path_outside":
            val = ["../../../../etc/passwd", "/etc/hostname", "/tmp", "", ".", "missing.stl",
                   "/proc/self/status", "C:\\mesh.stl", "box:1x1", "sphere:3", "x" * 5000,
                   "a\u0000b.stl", "fuzz.json", "../" * 40 + "cube.stl", "/dev/null",
                   "box:0x1x1"][int(rng.integers(16))]
            if rng.random() < 0.5:
                doc["container"]["path"] = val
                d += f" container.path = {val[:60]!r}"
            else:
                t = int(rng.integers(len(doc["types"])))
                doc["types"][t]["path"] = val
                d += f" types[{t}].path = {val[:60]!r}"
        elif mut == "nan_matrix":
            where = int(rng.integers(3))
            val = ["__NAN__", "__INF__", "__BIGFLOAT__"][int(rng.integers(3))]
            if where == 0:
                doc["container"]["frame_from_file"][1][1] = val
                d += f" container.frame_from_file[1][1] = {val}"
            elif where == 1:
                doc["types"][0]["local_from_file"][0][3] = val
                d += f" types[0].local_from_file[0][3] = {val}"
            else:
                doc["placements"][0]["matrix"][2][2] = val
                doc["placements"][0]["translation"][0] = val
                d += f" placements[0].matrix/translation = {val}"
        elif mut == "matrix_shape":
            val = [np.eye(3).tolist(), [[1, 0, 0, 0]] * 4 + [[0, 0, 0, 1]], "eye", [],
                   [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0]],
                   np.zeros((4, 4)).tolist()][int(rng.integers(6))]
            which = int(rng.integers(2))
            if which:
                doc["container"]["frame_from_file"] = val
                d += f" container.frame_from_file = {str(val)[:40]}"
            else:
                doc["types"][0]["local_from_file"] = val
                d += f" types[0].local_from_file = {str(val)[:40]}"
        elif mut == "many_placements":
            n = int(rng.choice([10_000, 50_000, 100_000]))
            p0 = doc["placements"][0]
            doc["placements"] = [p0] * n
            d += f" ({n} placements, all the same)"
        elif mut == "type_index":
            val = [-1, 2, 10**20, 1.0, "0", True, None][int(rng.integers(7))]
            k = int(rng.integers(len(doc["placements"])))
            doc["placements"][k]["type"] = val
            d += f" placements[{k}].type = {val!r}"
        elif mut == "rotation":
            q = [[0, 0, 0, 0], [1e-320, 0, 0, 0], [1e200, 1e200, 0, 0], [2, 0, 0, 0],
                 [0, 0, 0, 1e-30]][int(rng.integers(5))]
            p = doc["placements"][0]
            consistent = rng.random() < 0.7
            if consistent:
                doc["placements"][0] = self.placement(p["type"], q, p["translation"],
                                                      p["scale"])
            else:
                p["rotation"] = q
            d += (f" placements[0].rotation = {q} "
                  f"({'matrix recomputed' if consistent else 'matrix left'})")
        elif mut == "scale_consistent":
            s = float(rng.choice([0.0, -1.0, 1e-9, 1e9, 2.0, 1e300]))
            p = doc["placements"][0]
            doc["placements"][0] = self.placement(p["type"], p["rotation"], p["translation"], s)
            d += f" placements[0].scale = {s} (matrix recomputed)"
        elif mut == "translation_far":
            t = [float(rng.choice([1e3, 1e9, 1e300, -50.0])), 0.0, 0.0]
            p = doc["placements"][0]
            doc["placements"][0] = self.placement(p["type"], p["rotation"], t, p["scale"])
            d += f" placements[0].translation = {t} (matrix recomputed)"
        elif mut == "no_types":
            doc["types"] = []
            if rng.random() < 0.5:
                doc["placements"] = []
                d += " (and no placements)"
        elif mut == "meta_fields":
            which = int(rng.integers(9))
            if which == 0:
                doc["params"]["fidelity_detail"] = {"spheres": 8}
                d += " params.fidelity_detail = {spheres: 8}"
            elif which == 1:
                doc["params"]["attempts"] = [{"count": 1}, {}]
                d += " params.attempts = [{count:1}, {}]"
            elif which == 2:
                doc["params"]["repair"] = "none"
                d += " params.repair = 'none'"
            elif which == 3:
                doc["metrics"]["nni_per_type"] = 5
                d += " metrics.nni_per_type = 5"
            elif which == 4:
                doc["certificate"]["clearance"] = "abc"
                d += " certificate.clearance = 'abc'"
            elif which == 5:
                doc["params"]["warnings"] = 7
                d += " params.warnings = 7"
            elif which == 6:
                doc["params"]["stopped"] = ["deadline"]
                d += " params.stopped = ['deadline']"
            elif which == 7:
                doc["timings"] = {"load": "slow", "phase1": None}
                d += " timings = {load: 'slow', phase1: null}"
            else:
                doc["metrics"]["after_phase1"] = 3
                d += " metrics.after_phase1 = 3"
        elif mut == "clearance_param":
            val = ["abc", None, -5, "__NAN__", 1e300, [1]][int(rng.integers(6))]
            doc["params"]["clearance"] = val
            d += f" params.clearance = {val!r}"
        elif mut == "bigint":
            where = int(rng.integers(4))
            if where == 0:
                doc["container"]["volume"] = "__BIGINT__"
                d += " container.volume = 10**400"
            elif where == 1:
                doc["placements"][0]["translation"][1] = "__BIGINT__"
                d += " placements[0].translation[1] = 10**400"
            elif where == 2:
                doc["types"][0]["share"] = "__BIGINT__"
                d += " types[0].share = 10**400"
            else:
                doc["seed"] = "__BIGINT__"
                d += " seed = 10**400"
        elif mut == "truncated":
            text = json.dumps(doc)
            raw = text[: int(rng.integers(1, len(text) - 1))]
        elif mut == "garbage":
            raw = rng.integers(0, 256, size=int(rng.integers(1, 3000)), dtype=np.uint8).tobytes()
        elif mut == "empty":
            raw = ""
        elif mut == "bom":
            raw = "\ufeff" + json.dumps(doc)
            if rng.random() < 0.5:
                raw = json.dumps(doc).encode("utf-16")
                d += " (UTF-16)"
            else:
                d += " (UTF-8 BOM)"
        elif mut == "toplevel":
            raw = json.dumps([doc] if rng.random() < 0.5 else "jampacked.packing")
        elif mut == "deep_nesting":
            depth = int(rng.choice([1000, 100_000]))
            doc["params"]["x"] = "__DEEP__"
            raw = json.dumps(doc).replace('"__DEEP__"', "[" * depth + "]" * depth)
            d += f" (params.x nested {depth} deep)"
        elif mut == "dup_keys":
            raw = json.dumps(doc).replace('"version": 1', '"version": 1, "version": 7')
            d += " (version given twice, last 7)"
        elif mut == "valid":
            pass
        return raw, d

    @staticmethod
    def dump_doc(doc) -> str:
        text = json.dumps(doc, indent=1)
        return (text.replace('"__NAN__"', "NaN").replace('"__INF__"', "Infinity")
                .replace('"__BIGFLOAT__"', "1e400").replace('"__BIGINT__"', "1" + "0" * 400))

    # ----------------------------------------------------------------- running one case
    def run_case(self, plan: dict) -> dict:
        np = self.np
        kind, gen = plan["kind"], plan["gen"]
        rng = np.random.default_rng(plan["rseed"])
        folder = os.path.join(self.work, f"case_{plan['id']:05d}")
        shutil.rmtree(folder, ignore_errors=True)
        os.makedirs(folder)
        res = {"id": plan["id"], "kind": kind, "gen": gen, "fmt": plan.get("fmt"),
               "cls": None, "exc_type": None, "msg": None, "desc": None, "notes": [],
               "argv": None, "tb": None, "where": None, "seconds": None, "folder": folder}
        # ---- build
        try:
            call, meta = getattr(self, "build_" + kind)(plan, rng, folder)
        except Exception as exc:  # noqa: BLE001
            res.update(cls="h", exc_type=type(exc).__name__, msg=str(exc)[:300],
                       tb=traceback.format_exc()[-2000:])
            return res
        res["desc"] = meta.get("desc")
        res["argv"] = meta.get("argv")
        if self.args.dry:
            res["cls"] = "b"
            res["notes"].append("dry run: built only")
            return res
        inputs = meta.get("inputs", [])
        sentinel = meta.get("sentinel")  # (path, bytes) of an output that existed before
        before = {p: sha(p) for p in inputs if os.path.isfile(p)}
        before_tree = tree_hashes(folder)
        real_inputs = {os.path.realpath(p) for p in inputs}
        fresh_outputs = [p for p in meta.get("outputs", []) if not os.path.exists(p)
                         and os.path.realpath(p) not in real_inputs]
        # ---- run
        t0 = time.perf_counter()
        signal.signal(signal.SIGALRM, _alarm)
        signal.alarm(int(plan["limit"]))
        value, exc, tb = None, None, None
        try:
            value = call()
        except HarnessTimeout:
            signal.alarm(0)
            res.update(cls="d", exc_type="Timeout",
                       msg=f"no result after {plan['limit']} s (SIGALRM)",
                       seconds=time.perf_counter() - t0)
            res["restart"] = True
            return res
        except BaseException as e:  # noqa: BLE001
            exc, tb = e, traceback.format_exc()
        finally:
            signal.alarm(0)
        res["seconds"] = round(time.perf_counter() - t0, 3)
        # ---- classify
        try:
            if exc is not None:
                self.classify_exception(res, exc, tb, meta)
            else:
                self.classify_value(res, value, meta)
        except Outcome as o:
            res["cls"] = o.cls
            res["msg"] = res["msg"] or str(o)
            res["notes"].append(str(o))
        except BaseException as e:  # noqa: BLE001 - the oracle itself failed
            res["notes"].append(f"oracle failed: {type(e).__name__}: {e}"[:300])
            if res["cls"] is None:
                res["cls"] = "h"
                res["tb"] = traceback.format_exc()[-2000:]
        # ---- data loss checks
        for p, h in before.items():
            if sha(p) != h:
                res["notes"].append(f"input {os.path.basename(p)} changed")
                res["cls"] = "f" if res["cls"] not in ("c", "d") else res["cls"]
        project_failed = exc is not None or bool(
            meta.get("cli") and isinstance(value, tuple) and value[0] != 0)
        if sentinel is not None:
            sp, sbytes = sentinel
            if project_failed:
                cur = open(sp, "rb").read() if os.path.isfile(sp) else None
                if cur != sbytes:
                    res["notes"].append(f"pre-existing output {os.path.basename(sp)} changed "
                                        "or removed by a failed run")
                    if res["cls"] not in ("c", "d"):
                        res["cls"] = "f"
        if project_failed and meta.get("leftover_check"):
            for p in fresh_outputs:
                if os.path.isfile(p):
                    res["notes"].append(f"failed run left output {os.path.basename(p)}")
                    try:
                        meta["leftover_check"](p)
                    except Outcome as o:
                        res["notes"].append(str(o))
                        if res["cls"] != "c":
                            res["cls"] = "f"
                    except Exception as e:  # noqa: BLE001
                        res["notes"].append(f"leftover {os.path.basename(p)} unreadable: {e}"[:300])
                        if res["cls"] != "c":
                            res["cls"] = "f"
        after_tree = tree_hashes(folder)
        leftovers = [p for p in after_tree if p not in before_tree and ".tmp" in p]
        if leftovers:
            res["notes"].append(f"temp files left: {leftovers[:3]}")
            if res["cls"] not in ("c", "d"):
                res["cls"] = "f"
        return res

    def classify_exception(self, res, exc, tb, meta):
        res["exc_type"] = type(exc).__name__
        first = (str(exc).strip().splitlines() or [""])[0]
        res["msg"] = first[:400]
        debug = bool(meta.get("cli") and "--debug" in (meta.get("argv") or []))
        if isinstance(exc, self.errors.JampackedError) and (not meta.get("cli") or debug):
            res["cls"] = "a"
            self.note_message(res, str(exc), meta)
            if meta.get("expect") == "accept":
                res["notes"].append("rejected an input expected to be accepted/repaired")
            return
        res["cls"] = "c"
        if isinstance(exc, MemoryError):
            res["notes"].append("MemoryError (address-space limit of the worker)")
        lines = tb.strip().splitlines()
        res["tb"] = "\n".join(lines[-14:])
        frames = [ln.strip() for ln in lines if ln.strip().startswith("File ")]
        proj = [fr for fr in frames if PROJECT_MARK in fr or "/jampacked/" in fr]
        res["where"] = (proj[-1] if proj else (frames[-1] if frames else None))
        if res["where"]:
            res["where"] = res["where"].replace(PROJECT_MARK, "")

    def note_message(self, res, text, meta):
        if not text.strip():
            res["notes"].append("empty error message")
        named = meta.get("names")
        if named:
            if not any(n and n in text for n in named):
                res["notes"].append("message does not name the file")

    def classify_value(self, res, value, meta):
        check = meta.get("check")
        if meta.get("cli"):
            rc, out, err = value
            res["rc"] = rc
            res["stderr_tail"] = err.strip()[-600:]
            if "Traceback (most recent call last)" in err or "Traceback" in out:
                res["cls"] = "c"
                res["msg"] = "traceback printed"
                return
            if meta.get("validate_cli") and rc in (0, 1):
                res["cls"] = "b"  # 1 = some file is not watertight: a verdict, not an error
                note = check(value) if check else None
                if note:
                    res["notes"].append(note)
                return
            if rc != 0:
                lines = [ln for ln in err.strip().splitlines() if ln.strip()]
                msg = next((ln for ln in lines if ln.startswith("error:")
                            or "error:" in ln), lines[-1] if lines else "")
                res["msg"] = msg[:400]
                res["exc_type"] = f"exit {rc}"
                if not msg.strip():
                    res["cls"] = "c"
                    res["notes"].append("non-zero exit without any message")
                    return
                res["cls"] = "a"
                self.note_message(res, err, meta)
                if meta.get("expect") == "accept" and rc not in (1, 2):
                    res["notes"].append(f"unexpected exit status {rc}")
                if meta.get("expect") == "accept":
                    res["notes"].append("rejected an input expected to be accepted/repaired")
                return
            if meta.get("expect") == "reject":
                raise Outcome("e", "CLI exit 0 for an input that must be refused")
            res["cls"] = "b"
            if check:
                note = check(value)
                if note:
                    res["notes"].append(note)
            return
        if meta.get("expect") == "reject":
            raise Outcome("e", "accepted an input that must be refused")
        res["cls"] = "b"
        if check:
            note = check(value)
            if note:
                res["notes"].append(str(note)[:300])

    # ----------------------------------------------------------------- builders
    def build_load(self, plan, rng, folder):
        gen = plan["gen"]
        if gen == "huge":
            v, f, desc = self.geometry("huge", rng)
            p = os.path.join(folder, "huge.stl")
            self.write_mesh(p, "stl", v, f)
            exp = "accept"
        else:
            p, desc, exp, _ = self.mesh_file(gen, plan["fmt"], rng, folder)
        role = plan.get("role", "object")
        if exp == "accept" and role == "container" and gen in ("unreferenced_verts",):
            exp = "either"
        if role == "container" and exp == "accept":
            exp = "either"  # thin-wall test etc.
        if p.endswith(".3mf") and exp == "accept":
            exp = "either"  # core reads 3MF through trimesh (needs lxml)

        def call():
            return self.meshes.load_mesh(p, role=role)

        def check(md):
            self.check_meshdata(md)
            return f"{len(md.faces)} faces, {len(md.warnings)} warnings"

        return call, {"desc": f"load_mesh({os.path.basename(p)!r}, role={role}): {desc}",
                      "inputs": [p], "expect": exp, "check": check,
                      "names": [os.path.basename(p)]}

    def build_validate(self, plan, rng, folder):
        gen = plan["gen"]
        if gen == "huge":
            v, f, desc = self.geometry("huge", rng)
            p = os.path.join(folder, "huge.stl")
            self.write_mesh(p, "stl", v, f)
            vexp = "pass"
        else:
            p, desc, _, vexp = self.mesh_file(gen, plan["fmt"], rng, folder)
        fail_expected = vexp == "fail"

        def call():
            return self.validate.validate_file(p)

        def check(rep):
            d = rep.as_dict()
            try:
                json.dumps(d, allow_nan=False)
            except ValueError as e:
                raise Outcome("e", f"report.as_dict() is not strict JSON ({e}); "
                                   "'validate --json' would crash") from None
            if fail_expected and rep.passed:
                raise Outcome("e", f"validator PASSES a defective mesh ({gen}): {rep.summary()}")
            if vexp == "pass" and not rep.passed:
                raise Outcome("e", f"validator FAILS a valid mesh ({gen}): {rep.summary()}")
            return rep.summary()[:200]

        return call, {"desc": f"validate_file({os.path.basename(p)!r}): {desc}", "inputs": [p],
                      "expect": "either", "check": check, "names": [os.path.basename(p)]}

    def run_cli(self, argv):
        out, err = io.StringIO(), io.StringIO()
        old_cwd = os.getcwd()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            rc = self.cli_main.main(argv)
        os.chdir(old_cwd)
        return rc, out.getvalue(), err.getvalue()

    def build_cli_validate(self, plan, rng, folder):
        p, desc, _, vexp = self.mesh_file(plan["gen"], plan["fmt"], rng, folder)
        argv = ["validate", p]
        if rng.random() < 0.5:
            argv.append("--json")
        if rng.random() < 0.3:
            argv.append("--no-manifold3d")
        if rng.random() < 0.2:
            argv.insert(1, os.path.join(folder, "missing.stl"))
            vexp = "either"
        if rng.random() < 0.1:
            argv.insert(0, "--debug")

        def check(value):
            rc, out, _ = value
            if "--json" in argv:
                try:
                    json.loads(out)
                except ValueError as e:
                    raise Outcome("e", f"--json output is not JSON: {e}") from None
            if vexp == "fail" and rc == 0:
                raise Outcome("e", "validate exit 0 for a defective mesh")
            if vexp == "pass" and rc == 1:
                raise Outcome("e", "validate exit 1 (FAIL) for a valid mesh")
            return f"exit {rc}"

        def call():
            return self.run_cli(argv)

        return call, {"desc": f"jampacked {' '.join(argv)}: {desc}", "argv": argv,
                      "inputs": [p], "cli": True, "expect": "either", "check": check,
                      "names": [os.path.basename(p)], "validate_cli": True}

    # ---- pack
    def small_type(self, rng, folder, fmt, gen="good_sphere", stem="obj", size=8.0):
        return self.mesh_file(gen, fmt, rng, folder, size=size, stem=stem)

    def build_pack_api(self, plan, rng, folder):
        gen, fmt = plan["gen"], plan["fmt"]
        kw = dict(seed=int(rng.integers(0, 100)), time_budget=float(rng.choice([2.0, 3.0])),
                  fidelity="low")
        container = "box:30x30x30"
        tpath, tdesc, _, _ = self.small_type(rng, folder, fmt)
        types = [tpath]
        shares = None
        exp = "accept"
        desc = gen
        names = []
        if gen == "valid":
            if rng.random() < 0.5:
                t2, _, _, _ = self.small_type(rng, folder, fmt, "good_box", "obj2", 6.0)
                types.append(t2)
                shares = [float(rng.uniform(0.1, 1)), float(rng.uniform(0.1, 1))]
        elif gen == "container_mesh":
            g = str(rng.choice(["good_box", "good_sphere"]))
            container, cdesc, _, _ = self.mesh_file(g, fmt, rng, folder, size=32.0,
                                                    stem="container")
            desc += f" ({cdesc})"
            exp = "either"
        elif gen == "container_repairable":
            g = str(rng.choice(["inverted", "partial_flip", "dup_faces", "degenerate_faces",
                                "soup_split", "jitter_verts", "unreferenced_verts"]))
            if g == "unreferenced_verts" and fmt.startswith("stl"):
                g = "inverted"
            container, cdesc, _, _ = self.mesh_file(g, fmt, rng, folder, size=32.0,
                                                    stem="container")
            desc += f" ({cdesc})"
            exp = "either"
        elif gen == "container_bad":
            if rng.random() < 0.4:
                g = "raw:" + str(rng.choice(RAW_GENS))
            else:
                g = str(rng.choice([k for k, (le, _) in MESH_GENS.items() if le == "reject"]))
            f2 = fmt if not (g in NEEDS_INDEXED and fmt.startswith("stl")) else "obj"
            container, cdesc, _, _ = self.mesh_file(g, f2, rng, folder, size=32.0,
                                                    stem="container")
            desc += f" ({cdesc})"
            exp = "either"
            names = [container]
        elif gen == "type_bad":
            if rng.random() < 0.4:
                g = "raw:" + str(rng.choice(RAW_GENS))
            else:
                g = str(rng.choice([k for k, (le, _) in MESH_GENS.items() if le == "reject"]))
            f2 = fmt if not (g in NEEDS_INDEXED and fmt.startswith("stl")) else "obj"
            tp, cdesc, _, _ = self.mesh_file(g, f2, rng, folder, size=8.0, stem="badtype")
            types.append(tp)
            names = [tp]
            desc += f" ({cdesc})"
            exp = "either"
        elif gen == "type_repairable":
            g = str(rng.choice(["inverted", "partial_flip", "dup_faces", "degenerate_faces",
                                "opposite_pair", "soup_split", "jitter_verts", "sliver_body",
                                "scaled_tiny", "scaled_huge", "far_offset"]))
            tp, cdesc, _, _ = self.mesh_file(g, fmt, rng, folder, size=8.0, stem="reptype")
            types = [tp]
            if g == "scaled_tiny":
                kw["type_scale"] = 1e9
            elif g == "scaled_huge":
                kw["type_scale"] = 1e-9
            desc += f" ({cdesc}, type_scale {kw.get('type_scale', 1)})"
            exp = "either"
        elif gen == "box_spec":
            container = str(rng.choice(["box:1x2", "box:-1x2x3", "box:nanx1x1", "box:0x1x1",
                                        "box:1e308x1e308x1e308", "box:1e-300x1e-300x1e-300",
                                        "BOX: 30 × 30 × 30", "box:30x30x30x30", "box:",
                                        "box:infx1x1", "box:30X30X30", "box:1e6x1e6x1e6",
                                        "box:30x30x0.001"]))
            desc += f" container={container!r}"
            exp = "either"
        elif gen == "clearance":
            kw["clearance"] = float(rng.choice([-1.0, float("nan"), float("inf"), 1e300, 5.0,
                                                14.0, 1e-12]))
            desc += f" clearance={kw['clearance']}"
            exp = "either"
        elif gen == "shares":
            t2, _, _, _ = self.small_type(rng, folder, fmt, "good_box", "obj2", 6.0)
            types.append(t2)
            shares = [[0, 0], [-1, 2], [float("nan"), 1], [1], [1, 2, 3], [float("inf"), 1],
                      [1e-300, 1e-300], [0, 1], ["a", 1], [1e308, 1e308]][int(rng.integers(10))]
            desc += f" shares={shares}"
            exp = "either"
        elif gen == "seed":
            kw["seed"] = [-1, 2**64, 2**31, 1.5, "7", None][int(rng.integers(6))]
            desc += f" seed={kw['seed']!r}"
            exp = "either"
        elif gen == "time_budget":
            kw["time_budget"] = [0.0, -1.0, float("nan"), 1e-9, float("inf") if False else 0.5,
                                 "3"][int(rng.integers(6))]
            desc += f" time_budget={kw['time_budget']!r}"
            exp = "either"
        elif gen == "container_size":
            kw["container_size"] = [0.0, -5.0, float("nan"), float("inf"), 1e-300, 1e300, 1e4,
                                    1e-3, 300.0][int(rng.integers(9))]
            desc += f" container_size={kw['container_size']!r}"
            exp = "either"
        elif gen == "type_scale":
            kw["type_scale"] = [0.0, -1.0, float("nan"), float("inf"), 1e-300, 1e300, 1e-3,
                                100.0][int(rng.integers(8))]
            desc += f" type_scale={kw['type_scale']!r}"
            exp = "either"
        elif gen == "fidelity":
            kw["fidelity"] = str(rng.choice(["bogus", "LOW", "", "high", "auto"]))
            desc += f" fidelity={kw['fidelity']!r}"
            exp = "either"
        elif gen == "names":
            kw["names"] = [[], ["a", "b"], [""], [None], ["x" * 10000]][int(rng.integers(5))]
            desc += f" names={str(kw['names'])[:40]}"
            exp = "either"
        elif gen == "no_types":
            types = []
            desc += " types=[]"
            exp = "reject"
        elif gen == "type_huge_vs_container":
            tp, cdesc, _, _ = self.mesh_file("good_sphere", fmt, rng, folder, size=60.0,
                                             stem="bigtype")
            types = [tp]
            desc += " (sphere 60 in box 30)"
            exp = "reject"
        elif gen == "api_values":
            # what Python callers pass besides plain lists of str: paths, numpy scalars and
            # arrays, in-memory meshes, tuples, and the common slips (a bare string for the
            # list of types, None for a file)
            np = self.np
            k = int(rng.integers(10))
            exp = "either" if k >= 6 else "accept"
            if k == 0:
                types = [pathlib.Path(tpath)]
            elif k == 1:
                kw["seed"] = np.int64(5)
            elif k == 2:
                kw["container_size"] = np.float32(40.0)
            elif k == 3:
                shares = np.array([1.0])
            elif k == 4:
                container = self.meshes.box_mesh((30.0, 30.0, 30.0))
            elif k == 5:
                types = (tpath,)
            elif k == 6:
                types = tpath
            elif k == 7:
                types = [tpath, None]
            elif k == 8:
                container = None
            else:
                kw["type_scale"] = np.float64(0.9)
            desc += f" variant {k}"
        inputs = [p for p in [container, *types] if isinstance(p, str) and os.path.isfile(p)]

        def call():
            return self.api.pack(container, types, shares, use_cache=False, **kw)

        def check(pk):
            return self.check_packing(pk, container, types, kw.get("clearance", 0.0))

        shown = {k: v for k, v in kw.items()}
        return call, {"desc": f"pack({os.path.basename(str(container))!r}, "
                              f"{_shown_types(types)}, shares={shares}, "
                              f"{shown}): {desc}; type {tdesc}",
                      "inputs": inputs, "expect": exp, "check": check,
                      "names": [os.path.basename(n) for n in names]}

    def build_cli_pack(self, plan, rng, folder):
        gen, fmt = plan["gen"], plan["fmt"]
        tpath, tdesc, _, _ = self.small_type(rng, folder, fmt)
        container = "box:30x30x30"
        types = [tpath]
        out = os.path.join(folder, "out", "packing.json")
        os.makedirs(os.path.dirname(out))
        opts = ["--time-budget", str(rng.choice(["2", "3"])), "--fidelity", "low", "-q"]
        extra: list[str] = []
        exp = "accept"
        names = None
        sentinel = None
        if rng.random() < 0.3:
            sentinel = (out, b'{"old": "packing that must survive a failed run"}\n')
            with open(out, "wb") as fh:
                fh.write(sentinel[1])
        if gen == "valid":
            if rng.random() < 0.5:
                t2, _, _, _ = self.small_type(rng, folder, fmt, "good_box", "obj2", 6.0)
                types.append(t2 + "=" + str(rng.choice(["40%", "0.3", "2"])))
        elif gen == "clearance":
            extra = ["--clearance", str(rng.choice(["-1", "nan", "inf", "1e300", "abc", "",
                                                    "5", "14", "-0", "1e-320"]))]
            exp = "either"
        elif gen == "type_share":
            share = str(rng.choice(["0", "-1", "nan", "inf", "200%", "0%", "1e-300", "abc", "",
                                    "=", "100%", "1e999", "50 %", "0x10"]))
            types = [tpath + "=" + share]
            if rng.random() < 0.5:
                t2, _, _, _ = self.small_type(rng, folder, fmt, "good_box", "obj2", 6.0)
                types.append(t2 + ("=" + str(rng.choice(["0", "99%", "1"]))
                                   if rng.random() < 0.5 else ""))
            exp = "either"
        elif gen == "container_size":
            extra = ["--container-size", str(rng.choice(["0", "-5", "nan", "inf", "1e-300",
                                                         "1e300", "1e5", "1e-3", "abc",
                                                         "1e999"]))]
            exp = "either"
        elif gen == "type_scale":
            extra = ["--type-scale", str(rng.choice(["0", "-1", "nan", "1e-300", "1e300",
                                                     "1e-3", "100"]))]
            exp = "either"
        elif gen == "time_budget":
            opts = ["--fidelity", "low", "-q"]
            extra = ["--time-budget", str(rng.choice(["0", "-1", "nan", "inf", "1e-9", "abc",
                                                      "0.1"]))]
            exp = "either"
        elif gen == "seed":
            extra = ["--seed", str(rng.choice(["-1", "1.5", "abc", str(2**64), str(10**30),
                                               "007"]))]
            exp = "either"
        elif gen == "mix_tolerance":
            extra = ["--mix-tolerance", str(rng.choice(["-0.1", "2", "nan", "0", "1"]))]
            exp = "either"
        elif gen == "fidelity":
            opts = ["--time-budget", "2", "-q"]
            extra = ["--fidelity", str(rng.choice(["bogus", "LOW", ""]))]
            exp = "either"
        elif gen == "output":
            choice = int(rng.integers(5))
            if choice == 0:
                out = os.path.join(folder, "nope", "deeper", "p.json")
            elif choice == 1:
                out = folder
            elif choice == 2:
                out = tpath
            elif choice == 3:
                out = os.path.join(folder, "out", "")
            else:
                out = os.path.join(folder, "out", "p.stl")
            sentinel = None
            exp = "either"
        elif gen == "preview":
            extra = ["--preview", str(rng.choice([os.path.join(folder, "nodir", "p.png"), out,
                                                   tpath, os.path.join(folder, "out", "p.png"),
                                                   os.path.join(folder, "out", "p.txt")]))]
            exp = "either"
        elif gen == "box_spec":
            container = str(rng.choice(["box:1x2", "box:-1x2x3", "box:nanx1x1", "box:0x1x1",
                                        "box:1e308x1e308x1e308", "BOX: 30 × 30 × 30", "box:",
                                        "sphere:5", "box:1e6x1e6x1e6", "box:30x30x0.001",
                                        "C:/x.stl"]))
            exp = "either"
        elif gen == "container_bad":
            if rng.random() < 0.4:
                g = "raw:" + str(rng.choice(RAW_GENS))
            else:
                g = str(rng.choice([k for k, (le, _) in MESH_GENS.items() if le == "reject"]))
            f2 = fmt if not (g in NEEDS_INDEXED and fmt.startswith("stl")) else "obj"
            container, _, _, _ = self.mesh_file(g, f2, rng, folder, size=32.0, stem="container")
            names = [os.path.basename(container)]
            exp = "either"
        elif gen == "type_bad":
            if rng.random() < 0.4:
                g = "raw:" + str(rng.choice(RAW_GENS))
            else:
                g = str(rng.choice([k for k, (le, _) in MESH_GENS.items() if le == "reject"]))
            f2 = fmt if not (g in NEEDS_INDEXED and fmt.startswith("stl")) else "obj"
            tp, _, _, _ = self.mesh_file(g, f2, rng, folder, size=8.0, stem="badtype")
            types.append(tp)
            names = [os.path.basename(tp)]
            exp = "either"
        elif gen == "type_repairable":
            g = str(rng.choice(["inverted", "partial_flip", "dup_faces", "degenerate_faces",
                                "soup_split", "jitter_verts"]))
            tp, _, _, _ = self.mesh_file(g, fmt, rng, folder, size=8.0, stem="reptype")
            types = [tp]
            exp = "either"
        elif gen == "default_badargs":
            container = "default"
            extra = [str(rng.choice(["--clearance=-1", "--container-size=0",
                                     "--time-budget=0", "--type-scale=nan", "--seed=-3"]))]
            types = []
            exp = "reject"
        elif gen == "missing_args":
            choice = int(rng.integers(4))
            argv = [["pack"], ["pack", container], ["pack", container, "--type", tpath],
                    ["pack", "--type", tpath, "-o", out]][choice]
            inputs = [tpath]

            def call0():
                return self.run_cli(argv)

            return call0, {"desc": f"jampacked {' '.join(argv)}", "argv": argv, "cli": True,
                           "inputs": inputs, "expect": "reject", "names": None}
        argv = ["pack", container]
        for t in types:
            argv += ["--type", t]
        argv += ["-o", out] + opts + extra
        inputs = [p for p in [container] + [t.split("=")[0] for t in types] if os.path.isfile(p)]
        outputs = [out] + ([extra[1]] if gen == "preview" else [])

        def call():
            return self.run_cli(argv)

        def check(value):
            pk = self.packing.load_packing(out)
            return self.check_packing(pk, container, [t.split("=")[0] for t in types])

        def leftover(p):
            if p == out:
                try:
                    self.packing.load_packing(p)
                except Exception as e:  # noqa: BLE001
                    raise Outcome("f", f"half-written packing: {e}") from None

        return call, {"desc": f"jampacked {' '.join(argv)}", "argv": argv, "cli": True,
                      "inputs": inputs, "expect": exp, "check": check, "names": names,
                      "sentinel": sentinel, "outputs": outputs, "leftover_check": leftover}

    # ---- packing JSON consumers
    def packing_json(self, plan, rng, folder, mutate=True):
        mesh_container = rng.random() < 0.4
        doc, tpaths = self.base_packing(folder, rng, mesh_container)
        raw, d = (None, "valid")
        if mutate:
            raw, d = self.mutate_doc(doc, plan["gen"], rng, folder)
        jp = os.path.join(folder, "fuzz.json")
        if raw is None:
            raw = self.dump_doc(doc)
        with open(jp, "wb") as fh:
            fh.write(raw if isinstance(raw, bytes) else raw.encode("utf-8"))
        inputs = [jp] + tpaths + ([os.path.join(folder, "container.obj")]
                                  if mesh_container else [])
        return jp, doc, d, inputs

    def build_packing_load(self, plan, rng, folder):
        jp, _, d, inputs = self.packing_json(plan, rng, folder)

        def call():
            return self.packing.load_packing(jp)

        def check(pk):
            np = self.np
            for name in ("rotations", "translations", "scales", "frame_from_file"):
                if not np.all(np.isfinite(getattr(pk, name))):
                    raise Outcome("e", f"load_packing accepted non-finite {name}")
            problems = self.packing.verify_sources(pk)
            return f"{pk.n} placements; {len(problems)} source problems"

        exp = "accept" if plan["gen"] == "valid" else "either"
        return call, {"desc": f"load_packing(fuzz.json): {d}", "inputs": inputs,
                      "expect": exp, "check": check, "names": JSON_NAMES}

    def build_cli_info(self, plan, rng, folder):
        jp, _, d, inputs = self.packing_json(plan, rng, folder)
        argv = ["info", jp]

        def call():
            return self.run_cli(argv)

        return call, {"desc": f"jampacked info fuzz.json: {d}", "argv": argv, "cli": True,
                      "inputs": inputs, "expect": "either", "names": JSON_NAMES}

    def export_options(self, rng):
        """(ExportOptions kwargs, CLI args, description) for an options mutation."""
        mode = str(rng.choice(["parts", "union", "parts", "union", "connect"]))
        kw = {"mode": mode}
        cli = ["--mode", mode]
        op = int(rng.integers(12))
        d = f"mode {mode}"
        if op == 0:
            kw["shell"] = float(rng.choice([0.0, -1.0, float("nan"), 1e9, 0.5]))
            cli += [f"--shell={kw['shell']}"]
            d += f", shell {kw['shell']}"
        elif op == 1:
            at = float(rng.choice([0.0, 1.0, 2.0, 0.5, float("nan")]))
            kw["opening"] = ("plane", "+z", at)
            kw["shell"] = 1.0
            cli += ["--shell", "1", f"--open-plane=+z@{at}"]
            d += f", shell 1, open plane +z@{at}"
        elif op == 2:
            sz = float(rng.choice([-3.0, 0.0, 1e9, 10.0]))
            kw["shell"] = 1.0
            cli += ["--shell", "1", f"--window=+y@{sz}"]
            d += f", shell 1, window +y@{sz}"
            kw["opening"] = ("window", "+y", sz)
        elif op == 3:
            kw["drain"] = 2.0
            cli += ["--drain", "2"]
            d += ", drain without shell"
        elif op == 4:
            kw["resolution"] = float(rng.choice([1e9, 1e-12, 5.0, -1.0]))
            cli += [f"--resolution={kw['resolution']}"]
            d += f", resolution {kw['resolution']}"
        elif op == 5:
            kw["connector"] = float(rng.choice([1e-9, 1e6, 0.0]))
            cli += [f"--connector={kw['connector']}"]
            d += f", connector {kw['connector']}"
        elif op == 6:
            kw["split_files"] = True
            cli += ["--split"]
            d += ", split"
        elif op == 7:
            kw["up"] = str(rng.choice(["+q", "z", "-y"]))
            cli += [f"--up={kw['up']}"]
            d += f", up {kw['up']}"
        elif op == 8:
            cli += ["--open-plane", "+z@0.5"]
            d += ", open plane without shell"
            kw["opening_without_shell"] = True
        return kw, cli, d

    def build_export_api(self, plan, rng, folder):
        return self._build_export(plan, rng, folder, cli=False)

    def build_cli_export(self, plan, rng, folder):
        return self._build_export(plan, rng, folder, cli=True)

    def _build_export(self, plan, rng, folder, cli):
        gen = plan["gen"]
        jp, doc, d, inputs = self.packing_json(plan, rng, folder, mutate=gen != "options")
        names = None if gen == "options" else JSON_NAMES
        okw, ocli, od = ({"mode": str(rng.choice(["parts", "union"]))}, None, "")
        if gen == "options":
            okw, ocli, od = self.export_options(rng)
            d = "options: " + od
        else:
            ocli = ["--mode", okw["mode"]]
            d += f"; mode {okw['mode']}"
        outdir = os.path.join(folder, "exp")
        os.makedirs(outdir)
        ext = str(rng.choice(["stl", "3mf", "obj", "ply"]))
        outs = [os.path.join(outdir, f"out.{ext}")]
        r = rng.random()
        if r < 0.08:
            outs = [os.path.join(outdir, "out.xyz")]
        elif r < 0.14:
            outs = [jp]
        elif r < 0.2:
            outs = [os.path.join(folder, "cube.stl")]
        elif r < 0.25:
            outs = [os.path.join(folder, "nodir", "out.stl")]
        elif r < 0.35:
            outs.append(os.path.join(outdir, "out2.3mf"))
        sentinel = None
        if rng.random() < 0.3 and outs[0].startswith(outdir):
            sentinel = (outs[0], b"old export that must survive a failed run\n")
            with open(outs[0], "wb") as fh:
                fh.write(sentinel[1])
        d += f"; outputs {[os.path.relpath(o, folder) for o in outs]}"

        def leftover(p):
            self.check_outputs([p])

        def n_placements():
            if okw.get("mode") != "parts" or okw.get("split_files"):
                return None
            try:
                with open(jp, encoding="utf-8") as fh:
                    return len(json.load(fh)["placements"])
            except Exception:  # noqa: BLE001
                return None

        def geometry_check(written):
            """Independent volume check of union/parts outputs (no shell, one file)."""
            np = self.np
            import manifold3d as m3

            if not written or okw.get("shell") or okw.get("split_files") or okw.get(
                    "resolution"):
                return ""
            pk = self.packing.load_packing(jp)
            dets = [float(np.linalg.det((m @ pk.types[t].local_from_file)[:3, :3]))
                    for m, t in zip(pk.matrices(), pk.type_index, strict=True)]
            degenerate = [i for i, d_ in enumerate(dets) if abs(d_) < 1e-12]
            if degenerate:
                raise Outcome("e", f"export accepted {len(degenerate)} placement(s) whose "
                                   "transform (matrix @ local_from_file) is singular, i.e. "
                                   "objects of zero size, and wrote the file without them")
            meshes = {}
            solids = []
            for m, t in zip(pk.matrices(), pk.type_index, strict=True):
                if t not in meshes:
                    meshes[t] = self.meshes.load_mesh(pk.types[t].path)
                md = meshes[t]
                mm = m @ pk.types[t].local_from_file
                v = md.vertices @ mm[:3, :3].T + mm[:3, 3]
                f = md.faces if np.linalg.det(mm[:3, :3]) > 0 else md.faces[:, ::-1]
                solids.append(m3.Manifold(m3.Mesh64(
                    vert_properties=np.ascontiguousarray(v, np.float64),
                    tri_verts=np.ascontiguousarray(f, np.uint32))))
            if okw.get("mode") == "parts":
                expected = sum(x.volume() for x in solids)
            else:
                expected = m3.Manifold.batch_boolean(solids, m3.OpType.Add).volume()
            for p in written:
                got = self.validate.validate_file(p, check_manifold3d=False).volume
                if okw.get("mode") == "connect":
                    bad = got < expected * (1 - 1e-3)
                else:
                    bad = abs(got - expected) > 1e-3 * abs(expected) + 1e-9
                if bad:
                    raise Outcome("e", f"{os.path.basename(p)} volume {got:.6g}, but the "
                                       f"placed objects give {expected:.6g}")
            return "; volumes agree"

        def check(value):
            if cli:
                written = [p for p in outs if os.path.isfile(p)]
                if not written:
                    return "no files"
            else:
                written = list(value.paths)
            note = self.check_outputs(written, n_placements())
            return note + geometry_check(written)

        if cli:
            argv = ["export", jp]
            for o in outs:
                argv += ["-o", o]
            argv += ocli + ["-q"]

            def call():
                return self.run_cli(argv)

            shown = " ".join(os.path.relpath(a, folder) if a.startswith(folder) else a
                             for a in argv)
            return call, {"desc": f"jampacked {shown}: {d}",
                          "argv": argv, "cli": True, "inputs": inputs, "expect": "either",
                          "check": check, "names": names, "sentinel": sentinel,
                          "outputs": outs, "leftover_check": leftover}

        from jampacked.export.options import ExportOptions, Opening

        def call():
            kw = dict(okw)
            kw.pop("opening_without_shell", None)
            if kw.get("opening") is not None:
                kind, axis, x = kw["opening"]
                kw["opening"] = (Opening(kind=kind, axis=axis, at=x) if kind == "plane"
                                 else Opening(kind=kind, axis=axis, size=x))
            options = ExportOptions(**kw)
            return self.assemble.export_packing(jp, outs, options)

        return call, {"desc": f"export_packing(fuzz.json, {[os.path.basename(o) for o in outs]}, "
                              f"{okw}): {d}",
                      "inputs": inputs, "expect": "either", "check": check,
                      "names": names, "sentinel": sentinel, "outputs": outs,
                      "leftover_check": leftover}


def worker_main(args) -> None:
    # protocol on a private fd; anything printed to fd 1 by native code goes to stderr
    proto = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(2, 1)
    sys.stdout = sys.__stdout__ = os.fdopen(1, "w", buffering=1, closefd=False)
    if args.mem_gb:
        import resource

        lim = int(args.mem_gb * 2**30)
        resource.setrlimit(resource.RLIMIT_AS, (lim, lim))
    try:
        w = Worker(args)
        secs = 0.0 if args.no_warmup else w.warm_up()
        proto.write(json.dumps({"ready": True, "warmup_s": round(secs, 1)}) + "\n")
    except BaseException as e:  # noqa: BLE001
        proto.write(json.dumps({"ready": False, "error": traceback.format_exc()[-3000:]})
                    + "\n")
        raise SystemExit(3) from e
    for line in sys.stdin:
        plan = json.loads(line)
        res = w.run_case(plan)
        if not args.keep and res["cls"] in ("a", "b") and not plan.get("keep"):
            shutil.rmtree(res["folder"], ignore_errors=True)
        proto.write(json.dumps(res, default=str) + "\n")


# --------------------------------------------------------------------------------------------
# parent side


class WorkerProc:
    def __init__(self, args):
        self.args = args
        self.proc = None
        self.log = open(os.path.join(args.logdir, "worker.log"), "ab")

    def start(self) -> float:
        cmd = [sys.executable, os.path.abspath(__file__), "--worker", "--workdir",
               self.args.workdir, "--mem-gb", str(self.args.mem_gb)]
        if self.args.keep:
            cmd.append("--keep")
        if self.args.no_warmup:
            cmd.append("--no-warmup")
        if self.args.dry:
            cmd.append("--dry")
        env = dict(os.environ)
        env.setdefault("NUMBA_CACHE_DIR", os.path.join(self.args.root, "numba_cache"))
        env.setdefault("JAMPACKED_CACHE", os.path.join(self.args.root, "jp_cache"))
        env["PYTHONDONTWRITEBYTECODE"] = "1"
        env["PYTHONUNBUFFERED"] = "1"
        self.proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=self.log, env=env, start_new_session=True,
                                     cwd=self.args.workdir)
        msg = self.read(self.args.warmup_limit)
        if msg is None or not msg.get("ready"):
            self.kill()
            raise RuntimeError(f"worker did not start: {msg}")
        return msg.get("warmup_s", 0.0)

    def read(self, timeout: float):
        buf = b""
        end = time.monotonic() + timeout
        fd = self.proc.stdout.fileno()
        while True:
            left = end - time.monotonic()
            if left <= 0:
                return None
            r, _, _ = select.select([fd], [], [], left)
            if not r:
                return None
            chunk = os.read(fd, 1 << 20)
            if not chunk:
                return "EOF"
            buf += chunk
            if buf.endswith(b"\n"):
                return json.loads(buf.decode())

    def kill(self) -> None:
        if self.proc and self.proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait()
        self.proc = None

    def run(self, plan: dict):
        self.proc.stdin.write((json.dumps(plan) + "\n").encode())
        self.proc.stdin.flush()
        return self.read(plan["limit"] + GRACE)


def summarize(results: list[dict]) -> str:
    kinds = sorted({r["kind"] for r in results})
    lines = []
    head = f"{'kind':<14}" + "".join(f"{c:>6}" for c in CLASSES) + f"{'total':>7}"
    lines.append(head)
    for k in kinds:
        row = [r for r in results if r["kind"] == k]
        lines.append(f"{k:<14}" + "".join(f"{sum(r['cls'] == c for r in row):>6}"
                                          for c in CLASSES) + f"{len(row):>7}")
    lines.append(f"{'ALL':<14}" + "".join(f"{sum(r['cls'] == c for r in results):>6}"
                                         for c in CLASSES) + f"{len(results):>7}")
    lines.append("")
    lines += [f"  {c}: {CLASS_NAMES[c]}" for c in CLASSES]
    return "\n".join(lines)


def signatures(results: list[dict]) -> list[dict]:
    sig: dict[tuple, dict] = {}
    for r in results:
        if r["cls"] not in ("c", "d", "e", "f", "h"):
            continue
        key = (r["cls"], r.get("exc_type"), r.get("where") or (r.get("msg") or "")[:80])
        s = sig.setdefault(key, {"cls": r["cls"], "exc_type": r.get("exc_type"),
                                 "where": r.get("where"), "msg": r.get("msg"), "count": 0,
                                 "cases": [], "kinds": set(), "gens": set()})
        s["count"] += 1
        s["cases"].append(r["id"])
        s["kinds"].add(r["kind"])
        s["gens"].add(r["gen"])
    out = []
    for s in sorted(sig.values(), key=lambda s: (s["cls"], -s["count"])):
        s["kinds"] = sorted(s["kinds"])
        s["gens"] = sorted(s["gens"])
        s["cases"] = s["cases"][:20]
        out.append(s)
    return out


def parent_main(args) -> int:
    os.makedirs(args.root, exist_ok=True)
    os.makedirs(args.workdir, exist_ok=True)
    args.logdir = args.root
    ids = [args.only_id] if args.only_id is not None else list(range(args.n))
    plans = [plan_case(args.seed, i, args.huge_every) for i in ids]
    if args.only_kind:
        plans = [p for p in plans if p["kind"] in args.only_kind.split(",")]
    wp = WorkerProc(args)
    t_start = time.monotonic()
    warm = wp.start()
    print(f"worker ready (warm-up {warm:.1f} s); {len(plans)} cases, seed {args.seed}",
          flush=True)
    results = []
    restarts = 0
    for k, plan in enumerate(plans):
        if args.max_minutes and time.monotonic() - t_start > args.max_minutes * 60:
            print(f"stopping: --max-minutes {args.max_minutes} reached after {k} cases",
                  flush=True)
            break
        if args.only_id is not None:
            plan["keep"] = True
        t = time.monotonic()
        res = wp.run(plan)
        if res is None or res == "EOF":
            rc = wp.proc.poll() if wp.proc else None
            hang = res is None
            res = {"id": plan["id"], "kind": plan["kind"], "gen": plan.get("gen"),
                   "fmt": plan.get("fmt"), "cls": "d" if hang else "c",
                   "exc_type": "Timeout" if hang else f"worker died (rc {rc})",
                   "msg": (f"no answer within {plan['limit'] + GRACE} s (killed)" if hang
                           else "the worker process crashed"),
                   "notes": [], "seconds": round(time.monotonic() - t, 1),
                   "desc": None, "folder": os.path.join(args.workdir,
                                                        f"case_{plan['id']:05d}")}
            res["restart"] = True
        results.append(res)
        print(f"[{k + 1}/{len(plans)}] #{res['id']} {res['kind']:<13} {str(res['gen']):<24} "
              f"{res['cls']}  {res.get('seconds') or 0:>6}s  "
              f"{(res.get('exc_type') or '')[:22]:<22} {(res.get('msg') or '')[:90]}",
              flush=True)
        if res.get("restart"):
            wp.kill()
            restarts += 1
            warm = wp.start()
            print(f"   worker restarted (warm-up {warm:.1f} s)", flush=True)
        if args.out and (k % 10 == 9):
            write_report(args, results, restarts, time.monotonic() - t_start, partial=True)
    wp.kill()
    elapsed = time.monotonic() - t_start
    write_report(args, results, restarts, elapsed)
    print()
    print(summarize(results))
    print()
    sigs = signatures(results)
    if sigs:
        print("distinct findings (class, exception, where -> cases):")
        for s in sigs:
            print(f"  [{s['cls']}] {s['exc_type']} x{s['count']} at {s['where']}: "
                  f"{(s['msg'] or '')[:120]}  cases {s['cases'][:8]}  gens {s['gens'][:6]}")
    print(f"\n{len(results)} cases in {elapsed / 60:.1f} min, {restarts} worker restarts; "
          f"details in {args.out}")
    bad = [r for r in results if r["cls"] in args.fail_on]
    return 1 if bad else 0


def write_report(args, results, restarts, elapsed, partial=False):
    doc = {"seed": args.seed, "n": args.n, "cases_run": len(results), "partial": partial,
           "elapsed_s": round(elapsed, 1), "worker_restarts": restarts,
           "summary": {c: sum(r["cls"] == c for r in results) for c in CLASSES},
           "by_kind": {k: {c: sum(r["cls"] == c and r["kind"] == k for r in results)
                           for c in CLASSES} for k in sorted({r["kind"] for r in results})},
           "findings": signatures(results), "cases": results}
    tmp = args.out + ".tmp"
    with open(tmp, "w") as fh:
        json.dump(doc, fh, indent=1, default=str)
    os.replace(tmp, args.out)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=1000, help="number of cases (default 1000)")
    ap.add_argument("--seed", type=int, default=0)
    scratch = os.path.join(tempfile.gettempdir(), "jampacked-fuzz")
    ap.add_argument("--out", default=os.path.join(scratch, "report.json"),
                    help="JSON report path")
    ap.add_argument("--root", default=scratch, help="scratch root (caches, log)")
    ap.add_argument("--workdir", default=None, help="case folders (default ROOT/work)")
    ap.add_argument("--mem-gb", type=float, default=8.0, help="worker address-space limit")
    ap.add_argument("--huge-every", type=int, default=150,
                    help="one ~1.3M-face case every this many ids (0: none)")
    ap.add_argument("--only-id", type=int, default=None, help="run just this case id")
    ap.add_argument("--only-kind", default=None, help="comma list of kinds to run")
    ap.add_argument("--keep", action="store_true", help="keep every case folder")
    ap.add_argument("--max-minutes", type=float, default=0, help="stop after this long")
    ap.add_argument("--warmup-limit", type=float, default=900)
    ap.add_argument("--no-warmup", action="store_true",
                    help="skip the worker's warm-up pack (first pack case then compiles)")
    ap.add_argument("--dry", action="store_true",
                    help="only build the cases (tests the generators; runs no project code)")
    ap.add_argument("--fail-on", default="",
                    help="exit 1 when a case of these classes occurs (e.g. cdef)")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    args.workdir = args.workdir or os.path.join(args.root, "work")
    if args.worker:
        worker_main(args)
        return 0
    return parent_main(args)


if __name__ == "__main__":
    sys.exit(main())
