# The two set-up commands of the README: `make run` and `make test`.
JOBS   ?= $(shell nproc)
BUILD  ?= build
ASAN   ?= build-asan
OUT    ?= out
SCENE  ?= scenes/default.json

.PHONY: deps build build-asan run test fetch bench clean

deps:
	scripts/install-deps.sh

build: deps
	cmake -S . -B $(BUILD) -DCMAKE_BUILD_TYPE=Release >/dev/null
	cmake --build $(BUILD) -j $(JOBS)

build-asan: deps
	cmake -S . -B $(ASAN) -DCMAKE_BUILD_TYPE=Debug -DLAYERTRACE_SANITIZE=ON -DLAYERTRACE_COUNTERS=OFF -DLAYERTRACE_BENCH=OFF >/dev/null
	cmake --build $(ASAN) -j $(JOBS) --target layertrace_tests

fetch: deps
	scripts/fetch-scenes.sh

# The main job on the embedded default scene.
run: build
	@mkdir -p $(OUT)
	$(BUILD)/layertrace render $(SCENE) --tracer hssr --effect reflection --bounces 2 \
	    -o $(OUT)/default_hssr_reflection.png --stats $(OUT)/default_hssr_reflection.json
	$(BUILD)/layertrace layers $(SCENE) -o $(OUT)/layers --stats $(OUT)/layers.json --verify
	@echo "wrote $(OUT)/default_hssr_reflection.png (+ .json), $(OUT)/layers/ and $(OUT)/layers.json"

# The whole suite: Release tests (with the fetched scenes) and the unit tests under ASan+UBSan.
# The sanitizer build also compiles the per-ray counters out (LAYERTRACE_COUNTERS=OFF), so
# both configurations of the tracers are built and tested.
test: build build-asan fetch
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS)
	cd $(ASAN) && ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1 \
	    LAYERTRACE_SANITIZED=1 ctest --output-on-failure -j $(JOBS) -L unit

bench: build fetch
	$(BUILD)/bench_raster

clean:
	rm -rf $(BUILD) $(ASAN) $(OUT)
