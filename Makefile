# augrig: the two commands a fresh Debian 12 machine needs, and a few more.
#   make demo   install what is missing, configure, build, run the built-in simulated flight
#   make test   install what is missing, build, run every test (CTest)
#   make bench  build and run the benchmarks
BUILD ?= build
JOBS ?= $(shell nproc)
DEMO_OUT ?= out/demo

.PHONY: all deps configure build demo test bench format tidy clean

all: build

deps:
	bash scripts/install-deps.sh

$(BUILD)/build.ninja: CMakeLists.txt
	cmake -S . -B $(BUILD) -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo

configure: deps $(BUILD)/build.ninja

build: configure
	cmake --build $(BUILD) -j $(JOBS)

demo: build
	./$(BUILD)/augrig demo --out $(DEMO_OUT)

test: build
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS)

bench: build
	./$(BUILD)/bench_render

format:
	clang-format -i $$(git ls-files '*.cpp' '*.hpp')

tidy: configure
	clang-tidy -p $(BUILD) $$(git ls-files '*.cpp' | grep -v '^tests/')

clean:
	rm -rf $(BUILD)
