# Two commands on a fresh machine with only python3:
#   make demo   packs the bundled default scene (Spot the cow filled with fruit)
#   make test   runs the test suite
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test lint bench clean

$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	# numpy<2 keeps the environment compatible with Blender's bundled numpy (bpy 4.5).
	$(BIN)/pip install --quiet "numpy<2" -e ".[test]"
	touch $(STAMP)

demo: $(STAMP)
	mkdir -p out
	$(BIN)/jampacked pack default --time-budget 60 -o out/packing.json --preview out/preview.png

test: $(STAMP)
	$(BIN)/ruff check core export cli tests bench
	$(BIN)/python -m pytest -q

bench: $(STAMP)
	$(BIN)/python bench/run.py

clean:
	rm -rf $(VENV) out
