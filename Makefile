# The two set-up commands of the README: `make run` and `make test`.
JOBS   ?= $(shell nproc)
BUILD  ?= build
ASAN   ?= build-asan
TSAN   ?= build-tsan
FUZZ_SECONDS ?= 60
OUT    ?= out
# The sanitizer builds' debug information: line tables only (-g1), which the sanitizers' reports
# need for file and line, at a fraction of the full information's compile and link time.
SANITIZER_DEBUG_INFO ?= -g1
SCENE  ?= scenes/default.json

.PHONY: deps deps-run build build-cli build-asan build-fuzz build-tsan run test check fuzz fetch bench gpu-bundle clean

deps:
	scripts/install-deps.sh

deps-run:
	scripts/install-deps.sh --run

build: deps
	cmake -S . -B $(BUILD) -DCMAKE_BUILD_TYPE=Release -DBUILD_TESTING=ON -DLAYERTRACE_BENCH=ON >/dev/null
	cmake --build $(BUILD) -j $(JOBS)

# The CLI alone, in the same Release folder (make test later adds the tests and benchmarks to it
# without rebuilding the library).
build-cli: deps-run
	cmake -S . -B $(BUILD) -DCMAKE_BUILD_TYPE=Release -DBUILD_TESTING=OFF -DLAYERTRACE_BENCH=OFF >/dev/null
	cmake --build $(BUILD) -j $(JOBS) --target layertrace

# The sanitizer build is the Clang build: ASan+UBSan, the libFuzzer targets (libFuzzer needs
# clang; fuzz/README.md) and the unit tests come from one compile of the library. It also makes
# the library shared (BUILD_SHARED_LIBS): make test installs it and builds the examples against
# it, as the Release build (GCC) does with the static one.
build-asan: deps
	cmake -S . -B $(ASAN) -DCMAKE_CXX_COMPILER=clang++-16 -DCMAKE_BUILD_TYPE=Debug -DCMAKE_CXX_FLAGS_DEBUG=$(SANITIZER_DEBUG_INFO) -DLAYERTRACE_SANITIZE=ON -DLAYERTRACE_FUZZ=ON \
	    -DLAYERTRACE_COUNTERS=OFF -DLAYERTRACE_BENCH=OFF -DBUILD_SHARED_LIBS=ON -DLAYERTRACE_VIEWER=OFF >/dev/null
	cmake --build $(ASAN) -j $(JOBS) --target layertrace_tests layertrace_library layertrace fuzz_targets

build-fuzz: build-asan

# ThreadSanitizer build of the tests that run threads.
build-tsan: deps
	cmake -S . -B $(TSAN) -DCMAKE_BUILD_TYPE=Debug -DCMAKE_CXX_FLAGS_DEBUG=$(SANITIZER_DEBUG_INFO) -DLAYERTRACE_TSAN=ON -DLAYERTRACE_COUNTERS=OFF -DLAYERTRACE_BENCH=OFF -DLAYERTRACE_VIEWER=OFF >/dev/null
	cmake --build $(TSAN) -j $(JOBS) --target layertrace_tests

# Every fuzz target for FUZZ_SECONDS seconds; fails on any crash, leak or timeout.
fuzz: build-fuzz
	scripts/run-fuzz.sh $(ASAN) $(FUZZ_SECONDS)

fetch: deps
	scripts/fetch-scenes.sh

# The main job on the embedded default scene.
run: build-cli
	@mkdir -p $(OUT)
	$(BUILD)/layertrace render $(SCENE) --tracer hssr --effect reflection --bounces 2 -o $(OUT)/default_hssr_reflection.png
	$(BUILD)/layertrace layers $(SCENE) -o $(OUT)/layers --verify
	@echo "wrote $(OUT)/default_hssr_reflection.png (+ .json) and $(OUT)/layers/ (+ layers.json)"

# The whole suite: Release tests (with the fetched scenes, and the install of the static library
# with the examples built against it) and the unit tests under ASan+UBSan (with the shared library
# installed and the examples built against it).
# The sanitizer build also compiles the per-ray counters out (LAYERTRACE_COUNTERS=OFF), so
# both configurations of the tracers are built and tested.
# Then the unit tests under ThreadSanitizer, the fuzz targets of our own parsers for 20 s each
# (the assimp targets find assimp's bugs: `make fuzz`, docs/testing.md "Fuzzing"), and the vector
# loops and their test compiled for aarch64 (NEON) with the cross compiler.
# The scenes download while the three builds compile (the one is network-bound, the others
# CPU-bound); the fetch's output is shown once the builds are done.
test: deps
	@mkdir -p $(BUILD)
	@scripts/fetch-scenes.sh > $(BUILD)/fetch.log 2>&1 & fetch=$$!; \
	  $(MAKE) --no-print-directory build build-asan build-tsan || { kill $$fetch 2>/dev/null; exit 1; }; \
	  wait $$fetch; status=$$?; cat $(BUILD)/fetch.log; exit $$status
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS)
	cd $(ASAN) && ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1 \
	    LAYERTRACE_SANITIZED=1 ctest --output-on-failure -j $(JOBS) -L 'unit|install'
	cd $(TSAN) && TSAN_OPTIONS="halt_on_error=1 suppressions=$(CURDIR)/scripts/tsan.supp" \
	    LAYERTRACE_SANITIZED=1 ctest --output-on-failure -j $(JOBS) -L unit
	scripts/run-fuzz.sh $(ASAN) 20 json_scene cli texture
	scripts/cross-aarch64.sh

# The contributors' loop: the Release build of the CLI and the unit tests, and the unit and
# documentation tests (no fetched scenes, no sanitizers). Under 5 minutes after the first build.
check: deps
	cmake -S . -B $(BUILD) -DCMAKE_BUILD_TYPE=Release -DBUILD_TESTING=ON >/dev/null
	cmake --build $(BUILD) -j $(JOBS) --target layertrace layertrace_tests
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS) -L 'unit|docs'

# The CLI with the libraries it links and the benchmark's scenes, for scripts/gpu-bench.sh on a GPU
# machine without a compiler (docs/gpu.md).
gpu-bundle: build-cli fetch
	scripts/gpu-bundle.sh $(BUILD) $(OUT)/gpu-bundle

bench: build fetch
	$(BUILD)/bench_raster

clean:
	rm -rf $(BUILD) $(ASAN) $(TSAN) $(OUT)
