# qpbench: `make bench` and `make test` do all the set-up on a fresh machine.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# Debian packages that cyipopt builds against (IPOPT with MUMPS)
APT_PACKAGES := coinor-libipopt-dev liblapack-dev libblas-dev pkg-config

.PHONY: setup apt-packages test bench bench-large lint clean-results

# Idempotent: checks the Debian packages (fast) and reinstalls the venv only when
# pyproject.toml or this Makefile changed, or the venv is missing.
setup: apt-packages $(STAMP)

apt-packages:
	@missing=""; for p in $(APT_PACKAGES); do dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	if [ -n "$$missing" ]; then \
	  echo "apt-get install:$$missing"; \
	  SUDO=""; [ "$$(id -u)" -eq 0 ] || SUDO=sudo; \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq $$missing; \
	fi

$(STAMP): pyproject.toml Makefile
	@[ -x $(BIN)/python ] || $(PYTHON) -m venv $(VENV)
	@[ -x $(BIN)/uv ] || $(BIN)/pip install -q uv
	$(BIN)/uv pip install -q --python $(BIN)/python -e ".[dev,ipopt]"
	@touch $@

test: setup
	$(BIN)/python -m pytest -q

# The default benchmark: build the problem set, run every usable solver-formulation pair at
# every accuracy level, measure the simulator's scaling and pi-robust against one sparse
# factorization on large box packings, write results/REPORT.md.
# Re-running resumes: finished cells are skipped.
BENCH_SET ?= problems/default.toml
BENCH_PROBLEMS ?= build/problems/default
BENCH_RESULTS ?= results
BENCH_ACCURACY ?= 1e-2,1e-4,1e-6,1e-8,1e-10
BENCH_TIMEOUT ?= 10

bench: setup
	$(BIN)/qpbench build-set $(BENCH_SET) -o $(BENCH_PROBLEMS)
	$(BIN)/qpbench run $(BENCH_PROBLEMS) --accuracy $(BENCH_ACCURACY) --timeout $(BENCH_TIMEOUT) \
		-o $(BENCH_RESULTS)/bench.parquet
	$(BIN)/qpbench scaling -o $(BENCH_RESULTS)/scaling.json
	$(BIN)/qpbench speed -o $(BENCH_RESULTS)/speed.json
	$(BIN)/qpbench report $(BENCH_RESULTS)/bench.parquet -o $(BENCH_RESULTS)

# The larger sweep, in its own folders.
bench-large:
	$(MAKE) bench BENCH_SET=problems/large.toml BENCH_PROBLEMS=build/problems/large \
		BENCH_RESULTS=build/results-large BENCH_TIMEOUT=60

lint: setup
	$(BIN)/ruff check qpbench tests

# Forget the default benchmark's results (the next `make bench` starts afresh).
clean-results:
	rm -rf $(BENCH_RESULTS)/bench.parquet $(BENCH_RESULTS)/bench.parquet.parts \
		$(BENCH_RESULTS)/bench.parquet.lock
