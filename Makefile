# spinweb: set-up and common tasks. Only python3 (3.11+) is needed on the machine.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo demo-free test validate mutate bench clean

# the install: uv (from PyPI, into the venv) unpacks and byte-compiles the wheels in
# parallel, 18 s where pip takes 33 s on 2 cores (docs/testing.md); pip if uv cannot
$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install -qq uv && $(BIN)/uv pip install -q --compile-bytecode \
		--python $(BIN)/python -e '.[test]' || $(BIN)/python -m pip install -qq -e '.[test]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/spinweb run cases/demo.toml -o out/demo
	$(BIN)/spinweb plot out/demo/results.h5 --panels verdict -o out/demo/plot.png
	$(BIN)/spinweb render out/demo/results.h5 -o out/demo/web.png
	@$(BIN)/spinweb info --verdict out/demo/results.h5
	@echo "picture: out/demo/web.png   plot of what the verdict judged: out/demo/plot.png"
	@echo "results: out/demo/results.h5   ParaView: out/demo/web.pvd"

# the same web without the torque (free deployment): its verdict fails
demo-free: $(STAMP)
	$(BIN)/spinweb run cases/demo.toml -o out/demo_free --set 'control.law="free"' \
		--set 'title="demo web without the torque: free deployment"'
	$(BIN)/spinweb plot out/demo_free/results.h5 --panels verdict -o out/demo_free/plot.png
	$(BIN)/spinweb render out/demo_free/results.h5 -o out/demo_free/web.png
	@$(BIN)/spinweb info --verdict out/demo_free/results.h5
	@echo "picture: out/demo_free/web.png   plot of what the verdict judged: out/demo_free/plot.png"

test: $(STAMP)
	$(BIN)/python -m pytest -q -n 2 --dist worksteal

validate: $(STAMP)
	$(BIN)/python -m pytest -q -m slow -n 2 --dist worksteal

mutate: $(STAMP)
	$(BIN)/python tests/mutate.py

bench: $(STAMP)
	$(BIN)/python -m benchmarks.run_all

clean:
	rm -rf out .pytest_cache
