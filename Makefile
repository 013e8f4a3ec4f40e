# qpbench: `make bench` and `make test` do all the set-up on a fresh machine.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
APT_PACKAGES := coinor-libipopt-dev liblapack-dev libblas-dev pkg-config gfortran
JOBS ?= 2

.PHONY: setup test bench bench-large lint clean-results

setup: $(STAMP)

# Installs only what is missing: Debian packages Ipopt needs, the venv, the project.
$(STAMP): pyproject.toml Makefile
	@missing=""; for p in $(APT_PACKAGES); do dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	if [ -n "$$missing" ]; then \
	  echo "apt-get install:$$missing"; \
	  SUDO=""; [ "$$(id -u)" -eq 0 ] || SUDO=sudo; \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq $$missing; \
	fi
	@[ -x $(BIN)/python ] || $(PYTHON) -m venv $(VENV)
	@[ -x $(BIN)/uv ] || $(BIN)/pip install -q uv
	$(BIN)/uv pip install -q --python $(BIN)/python -e ".[dev,ipopt]"
	@touch $@

test: setup
	$(BIN)/python -m pytest -q

bench: setup
	$(BIN)/qpbench bench-default -o results

lint: setup
	$(BIN)/ruff check qpbench tests
