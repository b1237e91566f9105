# Two commands do all set-up on a fresh machine: `make run` and `make test`.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
ARGS ?=
PYTEST_ARGS ?=

.PHONY: run test test-all bench charts report-check browser clean

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $@

run: $(VENV)/.installed
	$(PY) pipeline.py $(ARGS)

# The tests open the HTML pages in a real browser: Debian's chromium, installed here when missing.
browser:
	@command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1 || \
		{ echo "installing chromium (apt-get) for the browser tests"; \
		  $$( [ "$$(id -u)" = 0 ] || echo sudo ) apt-get update -qq && \
		  DEBIAN_FRONTEND=noninteractive $$( [ "$$(id -u)" = 0 ] || echo sudo ) apt-get install -y -qq chromium >/dev/null; }

# One pytest worker per core (pytest-xdist), each test file whole on one worker.
XDIST := -n auto --dist loadfile

test: $(VENV)/.installed browser
	$(PY) -m pytest $(XDIST) $(PYTEST_ARGS)

test-all: $(VENV)/.installed browser
	$(PY) -m pytest -m '' $(XDIST) $(PYTEST_ARGS)

bench: $(VENV)/.installed
	$(PY) -m pip install --quiet -e '.[test,bench]'
	$(PY) benchmarks/run.py $(ARGS)

charts: $(VENV)/.installed
	$(PY) benchmarks/charts.py $(ARGS)

# Renders results/report.html in headless Chromium to results/report.png.
report-check: browser
	chromium --headless --no-sandbox --disable-gpu --disable-background-networking --no-first-run \
		--user-data-dir=$$(mktemp -d) --window-size=1300,4000 \
		--screenshot=$(CURDIR)/results/report.png file://$(CURDIR)/results/report.html
	@test -s results/report.png && echo "report.html rendered to results/report.png"

clean:
	rm -rf $(VENV) results .pytest_cache
