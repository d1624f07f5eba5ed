# stairbench: `make run` runs the main job, `make test` the tests. Both set up what they need
# (MuJoCo's shared library from the `mujoco` wheel on PyPI) on a fresh clone.

CARGO ?= cargo
BIN := target/release/stairbench
SCENARIO ?= scenarios/exp1.toml

SHELL := /bin/bash

.PHONY: all setup build run test test-slurm lint bench clean

all: build

setup:
	@./scripts/setup-mujoco.sh
	@./scripts/setup-pytools.sh
	@mkdir -p out

build: setup
	$(CARGO) build --release

# The main job: the closed-loop climb of the default scenario (the paper's Exp. 1) in MuJoCo,
# with the report per cycle; the JSON report goes to out/run.json. Exits non-zero when the
# climb fails.
run: build
	$(BIN) run $(SCENARIO) --json out/run.json

# Runs every test in release mode, then prints one total line ("N passed, N failed").
test: setup
	@set -o pipefail; $(CARGO) test --release 2>&1 | tee out/test.log
	@awk '/^test result:/ { p += $$4; f += $$6; i += $$8 } END { printf "stairbench: %d passed, %d failed, %d skipped\n", p, f, i }' out/test.log

# Shards on a real scheduler: a one-node Slurm started here (slurm-wlm and munge, installed
# if missing), `regress smoke` as an array of 4 shards, merged and compared case for case with
# a local run (the one `make test` just made, when it is newer than the binary); CI runs it.
test-slurm: build
	./scripts/slurm-smoke.sh $(BIN) target/tmp/regress/smoke/results.jsonl

# Formatting and clippy (the [lints] of Cargo.toml, warnings as errors); CI runs it.
lint: setup
	@$(CARGO) fmt --version >/dev/null 2>&1 && $(CARGO) clippy --version >/dev/null 2>&1 || rustup component add rustfmt clippy
	$(CARGO) fmt --check
	$(CARGO) clippy --release --all-targets -- -D warnings

bench: build
	$(BIN) bench lidar

clean:
	$(CARGO) clean
	rm -rf out
