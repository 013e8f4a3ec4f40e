# qpbench: `make bench` and `make test` do all the set-up on a fresh machine.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# Debian packages: what cyipopt builds against (IPOPT with MUMPS), what scikit-sparse builds
# against (SuiteSparse's CHOLMOD), and the browser the tests of results/index.html drive
# headless (Playwright with the system chromium)
APT_PACKAGES := coinor-libipopt-dev liblapack-dev libblas-dev pkg-config libsuitesparse-dev \
	chromium python3-siconos

.PHONY: setup apt-packages lock test bench bench-large lint clean-results

# Idempotent: checks the Debian packages (fast) and reinstalls the venv only when the lock,
# pyproject.toml or this Makefile changed, or the venv is missing. The venv gets exactly the
# versions of requirements.lock (hashes checked); `make lock` refreshes the lock on purpose.
UV_VERSION := 0.13.9
LOCK := requirements.lock
LOCK_EXTRAS := --extra dev --extra ipopt --extra build

setup: apt-packages $(STAMP)

apt-packages:
	@missing=""; for p in $(APT_PACKAGES); do dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	if [ -n "$$missing" ]; then \
	  echo "apt-get install:$$missing"; \
	  SUDO=""; [ "$$(id -u)" -eq 0 ] || SUDO=sudo; \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq $$missing; \
	fi

$(BIN)/uv:
	@[ -x $(BIN)/python ] || $(PYTHON) -m venv $(VENV)
	$(BIN)/pip install -q uv==$(UV_VERSION)

$(STAMP): $(LOCK) pyproject.toml Makefile | $(BIN)/uv
	@[ "$$($(BIN)/uv --version | cut -d' ' -f2)" = "$(UV_VERSION)" ] || $(BIN)/pip install -q uv==$(UV_VERSION)
	$(BIN)/uv pip sync -q --python $(BIN)/python --require-hashes --build-constraints $(LOCK) \
		$(LOCK)
	$(BIN)/uv pip install -q --python $(BIN)/python --no-deps --build-constraints $(LOCK) -e .
	@touch $@

# Re-resolve every package to its newest allowed release. Then run `make test` and
# `make bench`, and commit the lock together with the new results.
lock: $(BIN)/uv
	$(BIN)/uv pip compile -q --upgrade pyproject.toml $(LOCK_EXTRAS) --generate-hashes \
		--python-version 3.11 --python-platform x86_64-unknown-linux-gnu -o $(LOCK)

test: setup
	$(BIN)/python -m pytest -q

# The default benchmark: build the problem set, run every usable solver-formulation pair at
# every accuracy level, measure the simulator's scaling, pi-robust against one sparse
# factorization on large box packings and what inner accuracy costs whole simulations
# (sim-precision), write results/REPORT.md.
# Re-running resumes: finished cells are skipped.
BENCH_SET ?= problems/default.toml
BENCH_PROBLEMS ?= build/problems/default
BENCH_RESULTS ?= results
# the head-to-head's generated problems get seeds nobody tuned on: every family's seeds are
# offset by HEAD_TO_HEAD_SEED, drawn when make runs (the clock's seconds modulo 1e6) and fixed
# once drawn; `make bench HEAD_TO_HEAD_SEED=123` builds and measures that run's problems again
HEAD_TO_HEAD_SEED ?= $(shell expr $$(date +%s) % 1000000)
HEAD_TO_HEAD_SEED := $(HEAD_TO_HEAD_SEED)
HEAD_TO_HEAD_PROBLEMS ?= build/problems/head_to_head-$(HEAD_TO_HEAD_SEED)
# the set files the head-to-head's problems are built from, into one folder
HEAD_TO_HEAD_SETS ?= problems/head_to_head.toml
BENCH_ACCURACY ?= 1e-2,1e-4,1e-6,1e-8,1e-10
BENCH_TIMEOUT ?= 10
# main table: up to 5 timed repeats per solve (time_s their minimum), fewer once they have
# taken 10 ms in all: fast solves vary most between single timings; slow ones are not repeated
BENCH_REPEATS ?= --repeats 5 --repeat-budget 0.01
# frictional problems: two levels (staggered through cvxpy re-compiles every inner QP, so
# each of its solves takes seconds; five levels would double the benchmark's time)
BENCH_FRICTION_ACCURACY ?= 1e-4,1e-8

bench: setup
	$(BIN)/qpbench build-set $(BENCH_SET) -o $(BENCH_PROBLEMS)
	$(BIN)/qpbench run $(BENCH_PROBLEMS) --kind impact --accuracy $(BENCH_ACCURACY) \
		--timeout $(BENCH_TIMEOUT) $(BENCH_REPEATS) -o $(BENCH_RESULTS)/bench.parquet
	$(BIN)/qpbench run $(BENCH_PROBLEMS) --kind frictional --accuracy $(BENCH_FRICTION_ACCURACY) \
		--timeout $(BENCH_TIMEOUT) $(BENCH_REPEATS) -o $(BENCH_RESULTS)/bench.parquet
	$(BIN)/qpbench scaling --solver pi-robust --pile-steps 3 --box-pile-sizes 1000,10000 \
		-o $(BENCH_RESULTS)/scaling.json
	$(BIN)/qpbench speed -o $(BENCH_RESULTS)/speed.json
	$(BIN)/qpbench sequence --steps 40 --results $(BENCH_RESULTS)/bench.parquet \
		-o $(BENCH_RESULTS)/sequence.json
	$(BIN)/qpbench breakdown -o $(BENCH_RESULTS)/breakdown.json
	for set in $(HEAD_TO_HEAD_SETS); do \
		$(BIN)/qpbench build-set $$set --seed-offset $(HEAD_TO_HEAD_SEED) \
			-o $(HEAD_TO_HEAD_PROBLEMS) || exit $$?; \
	done
	$(BIN)/qpbench head-to-head $(HEAD_TO_HEAD_PROBLEMS) --results $(BENCH_RESULTS)/bench.parquet \
		-o $(BENCH_RESULTS)/head_to_head.json
	$(BIN)/qpbench sim-precision -o $(BENCH_RESULTS)/sim_precision.json
	$(BIN)/qpbench report $(BENCH_RESULTS)/bench.parquet -o $(BENCH_RESULTS)

# The larger sweep, in its own folders; first a fuzz run of FUZZ_CASES mutated scenes and as
# many mutated problem files through the command line (build/results-large/fuzz.json, whose
# counts the report prints). The target fails after the benchmark when a fuzz case failed.
# Its head-to-head adds problems/head_to_head_large.toml's piles of 10,000 bodies and
# Siconos' reduced granular flows.
FUZZ_CASES ?= 10000
bench-large: setup
	@mkdir -p build/results-large; status=0; \
	$(BIN)/qpbench fuzz --scenes $(FUZZ_CASES) --problems $(FUZZ_CASES) --seed 0 \
		-o build/results-large/fuzz.json || status=$$?; \
	$(MAKE) bench BENCH_SET=problems/large.toml BENCH_PROBLEMS=build/problems/large \
		BENCH_RESULTS=build/results-large BENCH_TIMEOUT=60 \
		HEAD_TO_HEAD_SEED=$(HEAD_TO_HEAD_SEED) \
		HEAD_TO_HEAD_SETS="problems/head_to_head.toml problems/head_to_head_large.toml" \
		HEAD_TO_HEAD_PROBLEMS=build/problems/head_to_head-large-$(HEAD_TO_HEAD_SEED) \
		&& exit $$status

lint: setup
	$(BIN)/ruff check qpbench tests

# Forget the default benchmark's results and the problem sets built for it (the next
# `make bench` starts afresh: a set is built incrementally, so problems captured by older
# code would otherwise stay).
clean-results:
	rm -rf $(BENCH_RESULTS)/bench.parquet $(BENCH_RESULTS)/bench.parquet.parts \
		$(BENCH_RESULTS)/bench.parquet.lock $(BENCH_PROBLEMS) build/problems/head_to_head-*
