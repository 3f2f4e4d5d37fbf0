# microcam: `make demo` runs the whole flow that exists so far, `make test`
# builds everything and runs every test (unit, property, golden, end-to-end,
# and the differential test against LinuxCNC's rs274).

CARGO ?= cargo
BIN   := target/release

.PHONY: bench-order all build test unit golden update-golden conformance checks fig3-20 removal-check dxf-check lint demo bench fuzz-smoke clean

all: build

build:
	$(CARGO) build --release --bins

# Release profile for tests too: one build serves the tests, the golden
# files, the conformance script and the benchmarks.
test: build unit conformance checks

unit:
	rm -rf target/corpus-tally
	$(CARGO) test --release
	scripts/corpus-tally

golden:
	$(CARGO) test --release --test golden

update-golden:
	UPDATE_GOLDEN=1 $(CARGO) test --release --test golden

# Conformance with tools nobody here wrote: LinuxCNC's rs274 interpreter
# (installs linuxcnc-uspace when missing) and the dls-pmaclib PMAC client
# against our controller emulator (installs dls-pmaclib when missing).
conformance: build
	python3 scripts/rs274-diff --gsim $(BIN)/gsim
	python3 scripts/pmac-conformance --emu $(BIN)/pmac-emu

# Checks against independent references.
checks: fig3-20 removal-check dxf-check

# dxf2chains against ezdxf on random drawings of every entity type and on
# the corpus (installs ezdxf when missing).
dxf-check: build
	python3 scripts/dxf-ezdxf-check --bin $(BIN)/dxf2chains

# Seed 000 Fig. 3-20: achieved feed against segment length under the PMAC model.
fig3-20: build
	python3 scripts/fig3-20 --gsim $(BIN)/gsim

# Material removal against exact mesh Booleans (installs manifold3d when missing).
removal-check: build
	python3 -c "import manifold3d" 2>/dev/null || python3 -m pip install -q manifold3d
	python3 scripts/removal-check --gsim $(BIN)/gsim

lint:
	$(CARGO) fmt --all -- --check
	$(CARGO) clippy --all-targets -- -D warnings

demo: build
	scripts/demo

# Benchmarks, each side by side with its anchor in one run.
bench: build
	scripts/bench/interp
	scripts/bench/dxf --bin $(BIN)/dxf2chains
	python3 -c "import manifold3d" 2>/dev/null || python3 -m pip install -q manifold3d
	scripts/bench/removal --gsim $(BIN)/gsim --passes 6000
	scripts/bench/upload
	scripts/bench/pathgen
	scripts/bench/loops
	scripts/bench/order --no-solver
	scripts/bench/arcfit

# Cut order against an independent TSP solver (LKH via elkai, installed into
# a private venv; the solver itself takes minutes).
bench-order: build
	scripts/bench/order

fuzz-smoke:
	scripts/fuzz-smoke

clean:
	$(CARGO) clean
	rm -rf out
