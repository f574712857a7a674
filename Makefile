# inbetween_jax -- common entry points. Everything runs inside .venv, created on first use.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
MODEL  ?= scvae
ARGS   ?=
RESULTS ?= results
PAIRS  ?= ../shared/data/cmu_pairs

.PHONY: help install install-bench test test-all bench bench-quick train lint-dupes clean-cache embedded-data demo infill preview

help:
	@echo "make install              create .venv and install the package with test extras"
	@echo "make test                 fast test suite (CI runs exactly this)"
	@echo "make test-all             include tests marked slow"
	@echo "make train MODEL=scvae    inbetween train MODEL ARGS (ARGS='--preset tiny train.num_steps=20 ...')"
	@echo "make bench                inbetween bench: baseline + model tables into $(RESULTS)/, then the speed section"
	@echo "                          (inbetween speed; installs the bench extra, torch, first; NO_SPEED=1 skips"
	@echo "                          both); the interaction model also on the real pairs in"
	@echo "                          \$$(PAIRS) (default ../shared/data/cmu_pairs) -> $(RESULTS)/pairs/"
	@echo ".venv/bin/inbetween --help  train / bench / infill / preview / demo"
	@echo "make demo                 inbetween demo: tiny runs of every model + infill with previews -> results/demo/"
	@echo "make infill ARGS='...'    .venv/bin/inbetween infill ARGS (see .venv/bin/inbetween infill --help)"
	@echo "make preview ARGS='...'   .venv/bin/inbetween preview ARGS (e.g. ARGS='FILE.bvh --gif --out DIR')"

$(PY):
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip

$(VENV)/.installed: pyproject.toml | $(PY)
	$(PY) -m pip install --quiet -e ".[test]"
	touch $@

install: $(VENV)/.installed

# the optional `bench` extra (torch, for the PyTorch columns of the speed section); `make bench` only, not `make test`
$(VENV)/.bench-installed: pyproject.toml | $(VENV)/.installed
	$(PY) -m pip install --quiet -e ".[bench]"
	touch $@

install-bench: $(VENV)/.bench-installed

test: install
	$(PY) -m pytest -q

test-all: install
	$(PY) -m pytest -q -m "slow or not slow"

train: install
	$(VENV)/bin/inbetween train $(MODEL) $(ARGS)

bench: install $(if $(NO_SPEED),,install-bench)
	$(VENV)/bin/inbetween bench --results $(RESULTS) $(ARGS)
	@if [ -d "$(PAIRS)" ]; then $(VENV)/bin/inbetween bench --source $(PAIRS) --models interaction --quick \
	    --results $(RESULTS)/pairs; else echo "no two-person capture in $(PAIRS): skipping the real-pair bench"; fi
ifeq ($(NO_SPEED),)
	$(VENV)/bin/inbetween speed --results $(RESULTS)
endif

demo: install
	$(VENV)/bin/inbetween demo

infill: install
	$(VENV)/bin/inbetween infill $(ARGS)

preview: install
	$(VENV)/bin/inbetween preview $(ARGS)

embedded-data: install
	$(PY) experiments/make_embedded_data.py --src ../shared/data/cmu_bvh --out inbetween_jax/assets/cmu30

clean-cache:
	rm -rf .cache ~/.cache/inbetween_jax
