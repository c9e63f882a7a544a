# augrig: the two commands a fresh Debian 12 machine needs, and a few more.
#   make demo   install what is missing, configure, build, run the built-in simulated flight
#   make test   install what is missing, build, run every test (CTest)
#   make bench  build and run the benchmarks
#   make sanitize  build everything with ASan+UBSan (build-asan/) and run every test under them
#   make fuzz   build the libFuzzer targets with clang (build-fuzz/) and run each FUZZ_SECONDS
BUILD ?= build
JOBS ?= $(shell nproc)
DEMO_OUT ?= out/demo
SANITIZE_BUILD ?= build-asan
FUZZ_BUILD ?= build-fuzz
FUZZ_SECONDS ?= 30
# Hardening builds run niced: they are long and should not starve an interactive build.
NICE ?= nice -n 10

.PHONY: all deps configure build demo test bench sanitize fuzz format tidy clean

all: build

deps:
	bash scripts/install-deps.sh

$(BUILD)/build.ninja: CMakeLists.txt
	cmake -S . -B $(BUILD) -G Ninja -DCMAKE_BUILD_TYPE=Release

configure: deps $(BUILD)/build.ninja

build: configure
	cmake --build $(BUILD) -j $(JOBS)

# The demo builds only the augrig binary and its libraries, not the tests and benches.
demo: configure
	cmake --build $(BUILD) -j $(JOBS) --target augrig
	./$(BUILD)/augrig demo --out $(DEMO_OUT)

test: build
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS)

bench: build
	./$(BUILD)/bench_render

# Every test under AddressSanitizer (leaks included) and UndefinedBehaviorSanitizer; the first report
# fails its test. Children (the tests that run the augrig binary) inherit the options. Leak
# suppressions, each justified: scripts/lsan.supp (system libraries only).
# Mesa's llvmpipe driver is preloaded so that it stays mapped until exit: eglTerminate() unloads
# it, and the blocks its globals held (LLVM's registries) then show as 240-byte leaks from an
# "<unknown module>" in every process that made a GL context. verify_asan_link_order=0 lets the
# preload come before the ASan runtime.
MESA_DRIVER := $(firstword $(wildcard /usr/lib/*/dri/swrast_dri.so))
SANITIZE_ENV = ASAN_OPTIONS=halt_on_error=1:detect_leaks=1:verify_asan_link_order=0 \
  UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1 \
  LSAN_OPTIONS=suppressions=$(CURDIR)/scripts/lsan.supp:print_suppressions=0 \
  LD_PRELOAD=$(MESA_DRIVER)
# -O1 and -g1 (line tables) build about twice as fast as -O2 -g and still give exact stacks.
sanitize: deps
	$(NICE) cmake -S . -B $(SANITIZE_BUILD) -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
	  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1" -DAUGRIG_SANITIZE=ON
	$(NICE) cmake --build $(SANITIZE_BUILD) -j $(JOBS)
	cd $(SANITIZE_BUILD) && $(SANITIZE_ENV) $(NICE) ctest --output-on-failure -j $(JOBS)

# libFuzzer needs clang; -O1 and line tables keep the instrumented build quick and the stacks exact.
fuzz: deps
	CC=clang CXX=clang++ $(NICE) cmake -S . -B $(FUZZ_BUILD) -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
	  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -gline-tables-only" -DAUGRIG_FUZZ=ON
	$(NICE) cmake --build $(FUZZ_BUILD) -j $(JOBS) --target fuzz_all
	$(NICE) bash fuzz/run.sh $(FUZZ_BUILD) $(FUZZ_SECONDS)

format:
	clang-format -i $$(git ls-files '*.cpp' '*.hpp')

# clang-tidy over every product .cpp, JOBS at a time with a line per file; fails on an error (a
# function over 150 lines is one, .clang-tidy).
tidy: configure
	JOBS=$(JOBS) bash scripts/tidy.sh $(BUILD)

clean:
	rm -rf $(BUILD)
