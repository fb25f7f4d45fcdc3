# The two commands: `make demo` and `make test`. Everything else is CMake.
BUILD ?= build
JOBS ?= $(shell nproc 2>/dev/null || echo 2)
CMAKE_FLAGS ?=

.PHONY: all deps configure build demo demo-office test sanitize fuzz bench format format-check clean

all: build

deps:
	sh scripts/install-deps.sh

configure: deps
	cmake -S . -B $(BUILD) -DCMAKE_BUILD_TYPE=Release $(CMAKE_FLAGS)

build: configure
	cmake --build $(BUILD) -j $(JOBS)

demo: build
	mkdir -p out
	$(BUILD)/penumbra render scenes/demo/demo.pbrt -o out/demo.exr --png out/demo.png --stats out/demo-stats.json

# The lighting-design demo (docs/lighting-design.md): the office rendered with its lux and cd/m2
# layers, its false-colour picture and its 0.75 m work-plane grid (CSV, JSON, isolux PNG).
demo-office: build
	mkdir -p out
	$(BUILD)/penumbra render scenes/office/office.pbrt -o out/office.exr --png out/office.png --exposure -9 --spp 16 --aov illuminance,luminance
	$(BUILD)/penumbra falsecolor out/office.exr --layer illuminance -o out/office-lux.png -s 1500 -cb
	$(BUILD)/penumbra illuminance scenes/office/office.pbrt --grid 0,0,12,8 --height 0.75 --spacing 0.5 -o out/office-grid.csv

test: build
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS)

# Unit tests again under AddressSanitizer and UndefinedBehaviorSanitizer (image tests excluded).
sanitize: deps
	cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DPN_SANITIZE=ON $(CMAKE_FLAGS)
	cmake --build build-asan -j $(JOBS)
	cd build-asan && ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1 \
	    ctest --output-on-failure -j $(JOBS) -LE slow

# The fuzz targets of tests/fuzz (clang's libFuzzer with ASan and UBSan; clang and its runtime
# are installed only for this), each run for FUZZ_SECONDS on its corpus; fails on any finding.
FUZZ_SECONDS ?= 60
fuzz:
	sh scripts/install-deps.sh clang libclang-rt-14-dev
	CC=clang cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo -DPN_FUZZ=ON -DPN_BUILD_TESTS=OFF $(CMAKE_FLAGS)
	cmake --build build-fuzz -j $(JOBS) --target pn_fuzz_targets
	sh tests/fuzz/run.sh build-fuzz $(FUZZ_SECONDS)

bench: build
	$(BUILD)/penumbra_bench --config bench/bench.conf --runs 3 --out bench/results

# The C files clang-format keeps in the style of .clang-format.
FORMAT_FILES = include/penumbra/*.h src/*/*.[ch] tests/*.[ch] bench/*.c bench/*/*.c

format:
	sh scripts/install-deps.sh clang-format
	clang-format -i $(FORMAT_FILES)

# Fails, naming the files, when a C file differs from what `make format` would make of it.
format-check:
	sh scripts/install-deps.sh clang-format
	clang-format --dry-run --Werror $(FORMAT_FILES)

clean:
	rm -rf $(BUILD) build-asan build-fuzz out
