# Two commands on a fresh machine with only python3:
#   make demo   packs the bundled default scene (Spot the cow filled with fruit) and exports
#               it as one watertight, validated print: out/spot.3mf + out/spot.stl
#   make test   runs the test suite
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test lint bench clean addon fuzz

$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	# numpy<2 keeps the environment compatible with Blender's bundled numpy (bpy 4.5).
	$(BIN)/pip install --quiet "numpy<2" -e ".[test]"
	touch $(STAMP)

demo: $(STAMP)
	mkdir -p out
	$(BIN)/jampacked pack default --time-budget 60 -o out/packing.json --preview out/preview.png
	$(BIN)/jampacked export out/packing.json --mode connect --shell 2 --up +y \
		--window +y@45 --drain 3 -o out/spot.3mf -o out/spot.stl --render out/spot.png
	$(BIN)/jampacked validate out/spot.3mf out/spot.stl

# first, alone, the tests that bound seconds (marked serial: among them the first run's
# compile, which fills numba's cache for the rest); then the rest on two processes
# (pytest-xdist), each file's tests on one of them, so that a module's fixtures are made once
test: $(STAMP)
	$(BIN)/ruff check core export cli addon tests bench
	$(BIN)/python -m pytest -q -m serial
	$(BIN)/python -m pytest -q -n 2 --dist loadfile -m "not serial"

bench: $(STAMP)
	$(BIN)/python bench/run.py

# Input fuzzing (bench/fuzz_inputs.py): N generated cases from SEED through the API and the
# CLI; fails when a case ends in a traceback, a hang, an invalid result or lost data.
# Report: out/fuzz-seed$(SEED).json. make fuzz SEED=3
SEED ?= 0
N ?= 1000
fuzz: $(STAMP)
	mkdir -p out
	nice -n 10 $(BIN)/python bench/fuzz_inputs.py --n $(N) --seed $(SEED) \
		--out out/fuzz-seed$(SEED).json --fail-on cdef

# Blender extension zip with the engine's wheels for linux-x64, windows-x64 and macos-arm64
# (downloads about 250 MB into addon/wheels/ once) -> dist/jampacked-<version>.zip
addon: $(STAMP)
	$(BIN)/python addon/build.py

clean:
	rm -rf $(VENV) out
