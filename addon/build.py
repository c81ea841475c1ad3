"""Build the Blender extension zip: wheels, manifest, validation, zip.

    python addon/build.py                      # all platforms -> dist/jampacked-<version>.zip
    python addon/build.py --split-platforms    # one zip per platform (smaller downloads)
    python addon/build.py --platforms linux-x64
    python addon/build.py --no-wheels          # the add-on code only (tests, development)
    python addon/build.py --check              # validate the manifest and wheels, no zip

Steps:
1. wheels (into ``addon/wheels/``, git-ignored, kept as a download cache): the jampacked
   wheel built from this repository, and the engine's dependencies for CPython 3.11 on each
   platform with ``pip download --only-binary=:all: --no-deps --platform ...`` at the
   versions pinned in :data:`PINS` (never numpy: Blender ships its own numpy 1.x; never bpy);
2. the manifest's ``wheels = [...]`` list is rewritten to match (``addon/blender_manifest.toml``
   in place for a full build, so that Blender's own ``extension build`` works on ``addon/``
   too; only inside the zip for ``--no-wheels`` and split builds);
3. validation: required fields and their form as Blender checks them (id, versions,
   tagline, license, permissions, ...), every listed wheel present, no numpy or bpy wheel,
   every platform given a wheel of every binary dependency; plus Blender's own validator
   (``blender_ext.py validate``) when the ``bpy`` module is installed;
4. the zip: the add-on's modules, the manifest and the wheels, at the zip's root.

Exit status 0 on success; on failure a message saying what is wrong and status 1.
This file is not part of the extension (it is left out of the zip).
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import re
import subprocess
import sys
import tomllib
import zipfile
from dataclasses import dataclass
from pathlib import Path

ADDON = Path(__file__).resolve().parent
REPO = ADDON.parent
WHEELS = ADDON / "wheels"
MANIFEST = ADDON / "blender_manifest.toml"

#: Blender extension platform -> pip platform tag (pip also accepts the older tags it
#: implies: manylinux_2_28 covers manylinux2014 wheels, macosx_12_0 covers 11_0 wheels).
#: Blender 4.2-4.5: Python 3.11; Linux needs glibc 2.28; macOS 12+ (scipy's oldest arm64
#: wheel at the pinned version).
PLATFORMS = {
    "linux-x64": "manylinux_2_28_x86_64",
    "windows-x64": "win_amd64",
    "macos-arm64": "macosx_12_0_arm64",
}
PYTHON = "3.11"
ABI = "cp311"

#: Binary dependencies (one wheel per platform) and pure-Python ones (one wheel for all),
#: at the versions the add-on is tested with (numpy<2, bpy 4.5). meshio needs rich, and rich
#: needs markdown-it-py, mdurl and pygments.
BINARY_PINS = {"numba": "0.68.1", "llvmlite": "0.50.0", "scipy": "1.17.1",
               "manifold3d": "3.5.4", "lxml": "6.1.3"}
PURE_PINS = {"trimesh": "5.2.0", "meshio": "5.3.5", "rich": "15.0.0",
             "markdown-it-py": "4.3.0", "mdurl": "0.1.2", "pygments": "2.21.0"}
PINS = {**BINARY_PINS, **PURE_PINS}
#: never bundled
FORBIDDEN = ("numpy", "bpy")

#: files of addon/ that are not part of the extension
EXCLUDE = {"build.py", "wheels", "__pycache__", ".gitignore"}

REQUIRED = {
    "schema_version": str, "id": str, "version": str, "name": str, "tagline": str,
    "maintainer": str, "type": str, "blender_version_min": str, "license": list,
}
OPTIONAL = {
    "blender_version_max": str, "website": str, "copyright": list, "permissions": dict,
    "tags": list, "platforms": list, "wheels": list, "build": dict,
}
PERMISSIONS = {"files", "network", "clipboard", "camera", "microphone"}
KNOWN_PLATFORMS = {"linux-x64", "linux-arm64", "windows-x64", "windows-arm64", "macos-x64",
                   "macos-arm64"}
VERSION_RE = re.compile(r"^\d+\.\d+\.\d+([-+][0-9A-Za-z.-]+)?$")


class BuildError(Exception):
    """Something is wrong with the manifest, the wheels or the build environment."""


# ----------------------------------------------------------------------------- wheels


@dataclass(frozen=True)
class Wheel:
    """A wheel file name, parsed (PEP 427)."""

    path: Path
    distribution: str
    version: str
    tags: tuple[str, str, str]

    @classmethod
    def parse(cls, path: Path) -> Wheel:
        parts = path.name[:-len(".whl")].split("-")
        if not path.name.endswith(".whl") or len(parts) not in (5, 6):
            raise BuildError(f"{path.name} is not a wheel file name "
                             "(name-version[-build]-python-abi-platform.whl)")
        return cls(path, _normal(parts[0]), parts[1], (parts[-3], parts[-2], parts[-1]))

    @property
    def pure(self) -> bool:
        return self.tags[2] == "any"

    def platform(self) -> str | None:
        """The Blender platform this wheel is for, None for pure wheels."""
        if self.pure:
            return None
        tag = self.tags[2]
        if "x86_64" in tag and "linux" in tag:
            return "linux-x64"
        if tag == "win_amd64":
            return "windows-x64"
        if tag.startswith("macosx") and ("arm64" in tag or "universal2" in tag):
            return "macos-arm64"
        return tag


def _normal(name: str) -> str:
    return re.sub(r"[-_.]+", "_", name).lower()


def _run(cmd: list[str]) -> None:
    print("+", " ".join(cmd), flush=True)
    done = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if done.returncode != 0:
        tail = "\n".join(done.stdout.splitlines()[-15:])
        raise BuildError(f"command failed ({done.returncode}): {' '.join(cmd)}\n{tail}")


def _existing(dist: str, version: str, platform: str | None) -> Path | None:
    for path in sorted(WHEELS.glob("*.whl")):
        w = Wheel.parse(path)
        if w.distribution == _normal(dist) and w.version == version and (
                w.pure or w.platform() == platform):
            return path
    return None


def build_jampacked_wheel() -> Path:
    """Build the jampacked wheel from this repository into addon/wheels/."""
    WHEELS.mkdir(exist_ok=True)
    for old in WHEELS.glob("jampacked-*.whl"):
        old.unlink()
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--quiet", "--wheel-dir",
          str(WHEELS), str(REPO)])
    found = sorted(WHEELS.glob("jampacked-*.whl"))
    if len(found) != 1:
        raise BuildError(f"building the jampacked wheel left {len(found)} wheels in {WHEELS}")
    return found[0]


def download_wheels(platforms: list[str], refresh: bool = False) -> list[Path]:
    """Download (or reuse) every pinned dependency wheel for the platforms."""
    WHEELS.mkdir(exist_ok=True)
    paths: list[Path] = []
    wanted: list[tuple[str, str, str | None]] = [(d, v, None) for d, v in PURE_PINS.items()]
    wanted += [(d, v, p) for p in platforms for d, v in BINARY_PINS.items()]
    for dist, version, platform in wanted:
        path = None if refresh else _existing(dist, version, platform)
        if path is None:
            tag = PLATFORMS[platform or "linux-x64"]
            _run([sys.executable, "-m", "pip", "download", "--quiet", "--only-binary=:all:",
                  "--no-deps", "--platform", tag, "--python-version", PYTHON,
                  "--implementation", "cp", "--abi", ABI, "--dest", str(WHEELS),
                  f"{dist}=={version}"])
            path = _existing(dist, version, platform)
            if path is None:
                raise BuildError(f"pip downloaded no wheel of {dist}=={version} for "
                                 f"{platform or 'all platforms'}")
        paths.append(path)
    return paths


def select_wheels(platforms: list[str]) -> list[Path]:
    """The wheels in addon/wheels/ for the platforms: jampacked, the pure pins, and the
    binary pins of each platform."""
    chosen: list[Path] = sorted(WHEELS.glob("jampacked-*.whl"))[-1:]
    for dist, version in PURE_PINS.items():
        path = _existing(dist, version, None)
        if path is not None:
            chosen.append(path)
    for platform in platforms:
        for dist, version in BINARY_PINS.items():
            path = _existing(dist, version, platform)
            if path is not None:
                chosen.append(path)
    return chosen


# ----------------------------------------------------------------------------- manifest


def wheels_block(paths: list[Path]) -> str:
    """The manifest's ``wheels = [...]`` lines for these wheels (paths relative to addon/)."""
    if not paths:
        return "wheels = []\n"
    lines = "".join(f'  "./wheels/{p.name}",\n' for p in paths)
    return f"wheels = [\n{lines}]\n"


_WHEELS_RE = re.compile(r"^wheels\s*=\s*\[.*?\][ \t]*\n", re.S | re.M)


def with_wheels(text: str, paths: list[Path], platforms: list[str] | None = None) -> str:
    """Manifest text with its wheels list (and optionally its platforms) replaced."""
    if not _WHEELS_RE.search(text):
        raise BuildError(f"{MANIFEST} has no 'wheels = [...]' list to fill in")
    text = _WHEELS_RE.sub(lambda _m: wheels_block(paths), text, count=1)
    if platforms is not None:
        listed = ", ".join(f'"{p}"' for p in platforms)
        text, n = re.subn(r"^platforms\s*=\s*\[.*?\]", f"platforms = [{listed}]", text,
                          count=1, flags=re.M | re.S)
        if n == 0:
            raise BuildError(f"{MANIFEST} has no 'platforms = [...]' list")
    return text


def _terse(value: str) -> str | None:
    if not value or value != value.strip() or len(value) > 64:
        return "must be 1-64 characters without surrounding spaces"
    if any(ord(c) < 32 for c in value):
        return "must not hold control characters"
    if not (value[-1].isalnum() or value[-1] in ")]}"):
        return "must not end with punctuation"
    return None


def validate_manifest(data: dict, base: Path, *, require_wheels: bool = True,
                      check_files: bool = True) -> list[str]:
    """Problems with a parsed manifest (empty when valid); ``base`` holds ./wheels/.

    require_wheels: every pinned dependency (and jampacked) must be listed, with a wheel of
    each binary one for every platform. check_files: every listed wheel must exist.
    """
    problems: list[str] = []
    for key, kind in REQUIRED.items():
        if key not in data:
            problems.append(f"missing required field '{key}'")
        elif not isinstance(data[key], kind):
            problems.append(f"'{key}' must be a {kind.__name__}")
    for key, value in data.items():
        if key not in REQUIRED and key not in OPTIONAL:
            problems.append(f"unknown field '{key}'")
        elif key in OPTIONAL and not isinstance(value, OPTIONAL[key]):
            problems.append(f"'{key}' must be a {OPTIONAL[key].__name__}")
    if problems:
        return problems
    if data["schema_version"] != "1.0.0":
        problems.append(f"schema_version must be \"1.0.0\", got {data['schema_version']!r}")
    ident = data["id"]
    if not ident.isidentifier() or "__" in ident or ident.startswith("_") or ident.endswith("_"):
        problems.append(f"id {ident!r} must be a Python identifier without leading, trailing "
                        "or double underscores")
    if not VERSION_RE.match(data["version"]):
        problems.append(f"version {data['version']!r} must be semantic (X.Y.Z)")
    if data["type"] != "add-on":
        problems.append(f"type must be \"add-on\", got {data['type']!r}")
    bmin = data["blender_version_min"]
    if not re.fullmatch(r"\d+\.\d+\.\d+", bmin):
        problems.append(f"blender_version_min {bmin!r} must be X.Y.Z")
    elif tuple(int(x) for x in bmin.split(".")) < (4, 2, 0):
        problems.append(f"blender_version_min {bmin} is older than 4.2.0, the first Blender "
                        "with extensions")
    if (err := _terse(data["tagline"])) is not None:
        problems.append(f"tagline {err}")
    if not data["license"] or not all(isinstance(x, str) and x.startswith("SPDX:")
                                      for x in data["license"]):
        problems.append("license must be a non-empty list of \"SPDX:...\" identifiers")
    for key, reason in data.get("permissions", {}).items():
        if key not in PERMISSIONS:
            problems.append(f"unknown permission '{key}' (one of {sorted(PERMISSIONS)})")
        elif not isinstance(reason, str) or (err := _terse(reason)) is not None:
            problems.append(f"permission '{key}': the reason {err or 'must be a string'}")
    if "files" not in data.get("permissions", {}):
        problems.append("permissions must include 'files' (export and caches write files)")
    for p in data.get("platforms", []):
        if p not in KNOWN_PLATFORMS:
            problems.append(f"unknown platform {p!r} (one of {sorted(KNOWN_PLATFORMS)})")
    wheels = data.get("wheels", [])
    parsed: list[Wheel] = []
    for entry in wheels:
        if not isinstance(entry, str) or "\\" in entry or not entry.endswith(".whl"):
            problems.append(f"wheel entry {entry!r} must be a relative path with '/' ending "
                            "in .whl")
            continue
        path = (base / entry).resolve()
        try:
            w = Wheel.parse(path)
        except BuildError as exc:
            problems.append(str(exc))
            continue
        if w.distribution in FORBIDDEN:
            problems.append(f"{path.name}: {w.distribution} must not be bundled (Blender "
                            "ships it)")
        pin = {_normal(d): v for d, v in PINS.items()}.get(w.distribution)
        if pin is not None and w.version != pin:
            problems.append(f"{path.name}: build.py pins {w.distribution} {pin}; run "
                            "addon/build.py to update the wheels")
        if check_files and not path.is_file():
            problems.append(f"listed wheel {entry} does not exist (run addon/build.py to "
                            "download it)")
        parsed.append(w)
    if require_wheels:
        names = {w.distribution for w in parsed}
        for dist in ["jampacked", *PINS]:
            if _normal(dist) not in names:
                problems.append(f"no wheel of {dist} is listed")
        for platform in data.get("platforms", []):
            have = {w.distribution for w in parsed if w.platform() == platform}
            for dist in BINARY_PINS:
                if _normal(dist) not in have:
                    problems.append(f"no {platform} wheel of {dist} is listed")
    return problems


def blender_validate(source: Path) -> str | None:
    """Run Blender's own manifest validator on a source folder or zip, if bpy is installed.

    Returns None when it passes or is unavailable, else its output.
    """
    spec = importlib.util.find_spec("bpy")
    if spec is None or not spec.origin:
        return None
    scripts = Path(spec.origin).parent
    found = sorted(scripts.glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py"))
    if not found:
        return None
    done = subprocess.run([sys.executable, str(found[-1]), "validate", str(source)],
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if done.returncode != 0:
        return done.stdout.strip() or f"exit status {done.returncode}"
    return None


# ----------------------------------------------------------------------------- zip


def addon_files() -> list[Path]:
    """The add-on's own files (modules and manifest), relative to addon/."""
    out = []
    for path in sorted(ADDON.rglob("*")):
        rel = path.relative_to(ADDON)
        if path.is_file() and not any(part in EXCLUDE for part in rel.parts) and (
                path.suffix in (".py", ".toml", ".md", ".txt")):
            out.append(rel)
    return out


def write_zip(out: Path, manifest_text: str, wheels: list[Path]) -> Path:
    """Write the extension zip: modules, the given manifest, wheels under wheels/."""
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_suffix(".zip.tmp")
    with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as zf:
        for rel in addon_files():
            if rel.name == MANIFEST.name:
                continue
            zf.write(ADDON / rel, rel.as_posix())
        zf.writestr(MANIFEST.name, manifest_text)
        for w in wheels:
            # wheels are zips already: store them
            zf.write(w, f"wheels/{w.name}", compress_type=zipfile.ZIP_STORED)
    os.replace(tmp, out)
    return out


def build(platforms: list[str], *, wheels: bool = True, split: bool = False,
          output_dir: Path = REPO / "dist", refresh: bool = False, check_only: bool = False,
          offline: bool = False, blender_check: bool = True) -> list[Path]:
    """Build (or, with check_only, validate) the extension; returns the zips written.

    A full build (every platform, one zip) also rewrites the wheels list of
    addon/blender_manifest.toml; subsets, split and --no-wheels builds only change the
    manifest inside their zips. check_only validates the manifest as it is.
    """
    for p in platforms:
        if p not in PLATFORMS:
            raise BuildError(f"unknown platform {p!r}: use {', '.join(PLATFORMS)}")
    template = MANIFEST.read_text(encoding="utf-8")
    data = tomllib.loads(template)
    version = data.get("version", "0")
    if check_only:
        problems = validate_manifest(data, ADDON, require_wheels=wheels)
        if problems:
            raise BuildError("the manifest is not valid:\n  - " + "\n  - ".join(problems))
        print(f"{MANIFEST.relative_to(REPO)} is valid ({len(data.get('wheels', []))} wheels)")
        return []
    if wheels and not offline:
        build_jampacked_wheel()
        download_wheels(platforms, refresh=refresh)
    full = wheels and not split and list(platforms) == list(PLATFORMS)
    if full:
        updated = with_wheels(template, select_wheels(platforms))
        if updated != template:
            MANIFEST.write_text(updated, encoding="utf-8")
            print(f"wrote the wheels list of {MANIFEST.relative_to(REPO)}")
        template = updated
    written: list[Path] = []
    for group in ([[p] for p in platforms] if split else [list(platforms)]):
        paths = select_wheels(group) if wheels else []
        text = template if full else with_wheels(template, paths, group)
        problems = validate_manifest(tomllib.loads(text), ADDON, require_wheels=wheels)
        if problems:
            raise BuildError("the manifest is not valid:\n  - " + "\n  - ".join(problems))
        suffix = f"-{group[0]}" if split else ""
        out = write_zip(output_dir / f"{data['id']}-{version}{suffix}.zip", text, paths)
        if blender_check:
            err = blender_validate(out)
            if err:
                out.unlink()
                raise BuildError(f"Blender's validator refuses {out.name}:\n{err}")
        size = out.stat().st_size / 1e6
        print(f"wrote {out} ({size:.1f} MB, {len(paths)} wheels)")
        written.append(out)
    return written


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--platforms", default=",".join(PLATFORMS),
                        help="comma-separated Blender platforms (default: %(default)s)")
    parser.add_argument("--split-platforms", action="store_true",
                        help="one zip per platform")
    parser.add_argument("--no-wheels", action="store_true",
                        help="the add-on code only (the engine must be installed otherwise)")
    parser.add_argument("--offline", action="store_true",
                        help="use the wheels already in addon/wheels/ (no build, no download)")
    parser.add_argument("--refresh", action="store_true", help="download the wheels again")
    parser.add_argument("--check", action="store_true",
                        help="validate the manifest and its wheels; write nothing")
    parser.add_argument("--no-blender-check", action="store_true",
                        help="skip Blender's own validator even if bpy is installed")
    parser.add_argument("--output-dir", type=Path, default=REPO / "dist")
    args = parser.parse_args(argv)
    platforms = [p.strip() for p in args.platforms.split(",") if p.strip()]
    try:
        build(platforms, wheels=not args.no_wheels, split=args.split_platforms,
              output_dir=args.output_dir, refresh=args.refresh, check_only=args.check,
              offline=args.offline, blender_check=not args.no_blender_check)
    except BuildError as exc:
        print(f"build failed: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())


__all__ = ["BuildError", "Wheel", "build", "main", "validate_manifest", "with_wheels"]
