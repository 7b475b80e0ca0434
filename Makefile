# szdyn: two commands do everything on a fresh machine: `make run` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
OUT    ?= results

.PHONY: run test derive bench regime venv clean

venv: $(STAMP)

# Create the virtual environment and install szdyn (editable) with the test/derive extras.
$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check -e '.[test]'
	touch $(STAMP)

## run: the thesis scenario on built-in defaults; CSV, JSON and PNG into $(OUT)/
run: $(STAMP)
	$(PY) -m szdyn.run --out $(OUT)

## test: the whole test suite
test: $(STAMP)
	$(PY) -m pytest -q

## regime: regime maps (interference x b_c, k_c, m_b) into $(OUT)/regime-*/ (a few minutes; resumable)
regime: $(STAMP)
	for axis in b_c k_c m_b; do $(PY) -m szdyn.run regime --second $$axis --out $(OUT)/regime-$$axis || exit 1; done

## derive: re-derive the model with SymPy and regenerate generated/
derive: $(STAMP)
	$(PY) -m derive --out generated
	# Numba keys a cached function on its own file only: after a regeneration, drop every
	# compiled cache so that nothing built against the old model is ever loaded.
	find generated src -name '*.nbi' -delete -o -name '*.nbc' -delete

## bench: benchmarks, written to BENCHMARKS.md
bench: $(STAMP)
	$(PY) bench/run_bench.py --out BENCHMARKS.md

clean:
	rm -rf $(VENV) $(OUT) .pytest_cache
	find . -name __pycache__ -prune -exec rm -rf {} +
