# Two commands do all set-up on a fresh machine: `make run` and `make test`.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
ARGS ?=
PYTEST_ARGS ?=

.PHONY: run test test-all bench charts report-check clean

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $@

run: $(VENV)/.installed
	$(PY) pipeline.py $(ARGS)

test: $(VENV)/.installed
	$(PY) -m pytest $(PYTEST_ARGS)

test-all: $(VENV)/.installed
	$(PY) -m pytest -m '' $(PYTEST_ARGS)

bench: $(VENV)/.installed
	$(PY) -m pip install --quiet -e '.[test,bench]'
	$(PY) benchmarks/run.py $(ARGS)

charts: $(VENV)/.installed
	$(PY) benchmarks/charts.py $(ARGS)

# Renders results/report.html in headless Chromium (apt-get install chromium) to results/report.png.
report-check:
	chromium --headless --no-sandbox --disable-gpu --disable-background-networking --no-first-run \
		--user-data-dir=$$(mktemp -d) --window-size=1300,4000 \
		--screenshot=$(CURDIR)/results/report.png file://$(CURDIR)/results/report.html
	@test -s results/report.png && echo "report.html rendered to results/report.png"

clean:
	rm -rf $(VENV) results .pytest_cache
