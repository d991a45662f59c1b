# spinweb: set-up and common tasks. Only python3 (3.11+) is needed on the machine.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test validate mutate bench clean

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install -qq --upgrade pip
	$(BIN)/python -m pip install -qq -e '.[test]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/spinweb run cases/demo.toml -o out/demo
	$(BIN)/spinweb plot out/demo/results.h5 -o out/demo/plot.png
	$(BIN)/spinweb render out/demo/results.h5 -o out/demo/web.png
	@echo "results: out/demo/results.h5, ParaView: out/demo/web.pvd, plot: out/demo/plot.png, picture: out/demo/web.png"

test: $(STAMP)
	$(BIN)/python -m pytest -q

validate: $(STAMP)
	$(BIN)/python -m pytest -q -m slow

mutate: $(STAMP)
	$(BIN)/python tests/mutate.py

bench: $(STAMP)
	$(BIN)/python -m benchmarks.run_all

clean:
	rm -rf out .pytest_cache
