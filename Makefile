# microcam: `make demo` runs the whole flow that exists so far, `make test`
# builds everything and runs every test (unit, property, golden, end-to-end,
# and the differential test against LinuxCNC's rs274).

CARGO ?= cargo
BIN   := target/release

.PHONY: demo-check modgraph samples-check pocket-compare dropcutter-check bench-order all build test unit golden update-golden conformance checks fig3-20 removal-check dxf-check lint demo bench fuzz-smoke clean

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

# Checks against independent references, and of the repository itself.
checks: fig3-20 removal-check dxf-check dropcutter-check modgraph samples-check demo-check

# The module layering (docs/architecture.md): no module uses one above it.
modgraph:
	python3 scripts/modgraph

# testdata/samples are exactly what scripts/make-samples writes.
samples-check:
	python3 scripts/make-samples --check

# pathgen dropcutter against OpenCAMLib (installs it into .venv).
dropcutter-check: build
	scripts/dropcutter-ocl-check --bin $(BIN)/pathgen

# dxf2chains against ezdxf on random drawings of every entity type and on
# the corpus (installs ezdxf when missing).
dxf-check: build
	python3 scripts/dxf-ezdxf-check --bin $(BIN)/dxf2chains

# Bayesteh (2013) Fig. 3-20: achieved feed against segment length under the PMAC model.
fig3-20: build
	python3 scripts/fig3-20 --gsim $(BIN)/gsim

# Material removal against exact mesh Booleans (installs manifold3d when missing).
# Grid pocket vs offsets on the case study (table in docs/pocket.md).
pocket-compare: build
	python3 scripts/pocket-compare --bin $(BIN)

removal-check: build
	python3 -c "import manifold3d" 2>/dev/null || python3 -m pip install -q manifold3d
	python3 scripts/removal-check --gsim $(BIN)/gsim

lint:
	$(CARGO) fmt --all -- --check
	$(CARGO) clippy --all-targets -- -D warnings

demo: build
	scripts/demo

# The demo's index page in a real headless browser (Debian's chromium): it
# loads and every picture it references exists and renders.
demo-check: demo
	scripts/demo-check

# Benchmarks, each side by side with its anchor in one run.
bench: build
	scripts/bench/interp
	scripts/bench/dxf --bin $(BIN)/dxf2chains
	python3 -c "import manifold3d" 2>/dev/null || python3 -m pip install -q manifold3d
	scripts/bench/removal --gsim $(BIN)/gsim --passes 6000
	scripts/bench/upload
	scripts/bench/stlverify
	scripts/bench/pathgen
	scripts/bench/loops
	scripts/bench/rays
	scripts/bench/order --no-solver
	scripts/bench/arcfit
	scripts/bench/feedopt
	scripts/bench/plough2d
	scripts/bench/dropcutter --bin $(BIN)/pathgen

# Cut order against an independent TSP solver (LKH via elkai, installed into
# a private venv; the solver itself takes minutes).
bench-order: build
	scripts/bench/order

fuzz-smoke:
	scripts/fuzz-smoke

clean:
	$(CARGO) clean
	rm -rf out
