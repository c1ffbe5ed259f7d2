# One entry point for a fresh Debian 12 machine (as root) or a developer's clone:
#   make test   - apt packages, .venv (Python 3.11 + bpy), build the core, run the whole suite
#   make demo   - solve and bake example_blends/cornell_box.blend headless, write out/
#   make bench  - benchmarks, figures to bench/results.json
# Every target does its own set-up and is fast when everything is in place.

VENV       ?= .venv
PY         := $(VENV)/bin/python
PYTEST_ARGS ?=
APT_PACKAGES := libembree-dev libtbb-dev libegl1 libegl-mesa0 libgl1-mesa-dri libxi6 libxxf86vm1 libllvm19 \
                libxfixes3 libxrender1 libxkbcommon0 libsm6 cmake g++ make
PYTHON311  ?= $(shell command -v python3.11 2>/dev/null || ls $(HOME)/.pyenv/versions/3.11*/bin/python3.11 2>/dev/null | tail -n 1)
CORE_SOURCES := $(shell find core_cpp python -type f \( -name '*.cpp' -o -name '*.h' -o -name '*.py' -o -name CMakeLists.txt \)) pyproject.toml

.PHONY: test test-fast demo bench apt venv build clean

test: build
	$(PY) -m pytest $(PYTEST_ARGS)

# Skips the slow reference comparisons (Cycles renders, Mitsuba 3).
test-fast: build
	$(PY) -m pytest --skip-slow $(PYTEST_ARGS)

demo: build
	$(PY) example_blends/make_cornell_box.py --if-missing
	$(PY) addon/cli.py example_blends/cornell_box.blend --out out/cornell_box_solved.blend --render out/cornell_box.png

bench: build
	$(PY) bench/run.py

apt: $(VENV)/.apt-stamp
$(VENV)/.apt-stamp:
	@if dpkg -s $(APT_PACKAGES) python3.11 python3.11-venv >/dev/null 2>&1; then echo "apt packages present"; \
	else apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $(APT_PACKAGES) python3.11 python3.11-venv; fi
	@mkdir -p $(VENV) && touch $@

venv: $(VENV)/.deps-stamp
$(VENV)/.deps-stamp: requirements-dev.txt $(VENV)/.apt-stamp
	@py="$(PYTHON311)"; [ -n "$$py" ] || py=/usr/bin/python3.11; \
	[ -x $(VENV)/bin/python ] || "$$py" -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -r requirements-dev.txt
	touch $@

build: $(VENV)/.build-stamp
$(VENV)/.build-stamp: $(VENV)/.deps-stamp $(CORE_SOURCES)
	$(PY) -m pip install -q --no-build-isolation --no-deps .
	touch $@

clean:
	rm -rf build out $(VENV)
