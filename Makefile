# stairbench: `make run` runs the main job, `make test` the tests. Both set up what they need
# (MuJoCo's shared library from the `mujoco` wheel on PyPI) on a fresh clone.

CARGO ?= cargo
BIN := target/release/stairbench
SCENARIO ?= scenarios/exp1.toml

.PHONY: all setup build run test lint bench clean

all: build

setup:
	@./scripts/setup-mujoco.sh

build: setup
	$(CARGO) build --release

# The main job: today a simulated lidar scan of the default scenario (the paper's Exp. 1).
run: build
	$(BIN) scan $(SCENARIO) -o out/exp1.ply

test: setup
	$(CARGO) test --release

lint: setup
	$(CARGO) fmt --check
	$(CARGO) clippy --release --all-targets -- -D warnings

bench: build
	$(BIN) bench lidar

clean:
	$(CARGO) clean
	rm -rf out
