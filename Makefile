# wavefuel: GNU make build. `make` builds bin/wavefuel and lib/libwavefuel.a; `make run` and `make test`
# first install missing Debian packages through tools/install-deps.sh.
CC       ?= gcc
BUILD    ?= build
OPENMP   ?= 1
WERROR   ?= 0
HDF5_CFLAGS := $(shell pkg-config --cflags hdf5-serial 2>/dev/null)
HDF5_LIBS   := $(shell pkg-config --libs hdf5-serial 2>/dev/null)
GIT_HASH := $(shell git describe --always --dirty 2>/dev/null || echo unknown)

CFLAGS   ?= -O2 -g
# `override`: the project's flags stay when CFLAGS/LDFLAGS come from the command line (sanitize, fuzz, tsan).
# Floating point: -ffp-contract=off (no FMA contraction: the same bits on every CPU and in every SIMD width),
# -fno-math-errno and -fno-trapping-math (nothing reads errno or the FP exception flags; these let the compiler
# inline sqrt and if-convert selects so that loops vectorise, and change no computed value); the dynamic
# vectoriser cost model (that of -O3) because -O2's very-cheap one skips loops of unknown trip count.
override CFLAGS += -std=c11 -D_GNU_SOURCE -Wall -Wextra -Wpedantic -Wshadow -Wstrict-prototypes \
            -ffp-contract=off -fno-fast-math -fno-math-errno -fno-trapping-math -Iinclude -Isrc $(HDF5_CFLAGS) -MMD -MP
ifeq ($(WERROR),1)
override CFLAGS += -Werror
endif
ifeq ($(findstring clang,$(shell $(CC) --version 2>/dev/null | head -1)),)
override CFLAGS += -fvect-cost-model=dynamic
else
# clang (fuzz and TSan builds) warns when an `omp simd` loop does not vectorise at its -O1; the loop is still right.
override CFLAGS += -Wno-pass-failed
endif
ifeq ($(OPENMP),1)
override CFLAGS += -fopenmp
override LDFLAGS += -fopenmp
else
override CFLAGS += -Wno-unknown-pragmas
endif
# -lhdf5_hl: HDF5's high-level library (H5LT), which the readers use; in the same directory as -lhdf5, before it.
LDLIBS   += -lhdf5_hl $(HDF5_LIBS) -lsundials_cvodes -lsundials_arkode -lsundials_nvecserial -lsundials_nvecopenmp \
            -lsundials_sunlinsolspgmr -lsundials_sunnonlinsolfixedpoint -lsundials_sunnonlinsolnewton \
            -lsundials_generic -lyaml -llapacke -llapack -lgsl -lgslcblas -lsleef -lm

LIB_SRC  := $(sort $(wildcard src/*/*.c src/*/*/*.c))
LIB_SRC  := $(filter-out src/cli/% src/mpi/%,$(LIB_SRC))
CLI_SRC  := $(sort $(wildcard src/cli/*.c))
TEST_SRC := $(sort $(wildcard tests/test_*.c))
BENCH_SRC:= $(sort $(wildcard bench/*.c))
# Small programs built from the library for the scripts of tools/ (tools/keydoc.c: the generated doc tables).
TOOL_SRC := $(sort $(wildcard tools/*.c))
LIB_OBJ  := $(LIB_SRC:%.c=$(BUILD)/%.o)
CLI_OBJ  := $(CLI_SRC:%.c=$(BUILD)/%.o)
TEST_BIN := $(TEST_SRC:tests/%.c=$(BUILD)/tests/%)
BENCH_BIN:= $(BENCH_SRC:bench/%.c=$(BUILD)/bench/%)
TOOL_BIN := $(TOOL_SRC:tools/%.c=$(BUILD)/tools/%)
PLUGIN_SO:= $(patsubst examples/plugins/%.c,$(BUILD)/plugins/%.so,$(sort $(wildcard examples/plugins/*.c)))
# Fuzz targets (fuzz/README.md): *_replay feed saved inputs to a target and are built with $(CC) as part of
# `tests`; *_fuzzer are the libFuzzer binaries, built with clang in build-fuzz/ by fuzz/run.sh.
FUZZ_TARGETS := scenario vehicle csv
FUZZ_SECONDS ?= 60
REPLAY_BIN   := $(FUZZ_TARGETS:%=$(BUILD)/fuzz/%_replay)
FUZZER_BIN   := $(FUZZ_TARGETS:%=$(BUILD)/fuzz/%_fuzzer)
LIBA     := lib/libwavefuel.a
BIN      := bin/wavefuel

.PHONY: all run test check sanitize deps clean bench tests fuzz fuzz-smoke fuzzers tsan valgrind python
all: $(BIN) $(LIBA)

deps:
	@./tools/install-deps.sh

$(BUILD)/%.o: %.c Makefile
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS) -c $< -o $@

# Tests, benchmarks and fuzz targets find the repository's files (vehicles/, tests/data/, ../shared/data) by its
# source path; the library and the programs have no build-tree path compiled in (docs/energy.md: search paths).
$(BUILD)/tests/%.o $(BUILD)/bench/%.o $(BUILD)/fuzz/%.o: override CFLAGS += -DWF_REPO_DIR='"$(CURDIR)"'

# `git describe` goes to src/util/version.c alone (wf_git_hash), which depends on a file holding it, rewritten only
# when it changes: an incremental build recompiles that one file, and results never record an older tree's hash.
GIT_STAMP := $(BUILD)/git_hash
$(shell mkdir -p $(BUILD) && (echo '$(GIT_HASH)' | cmp -s - $(GIT_STAMP) || echo '$(GIT_HASH)' > $(GIT_STAMP)))
$(BUILD)/src/util/version.o $(BUILD)/pic/src/util/version.o: $(GIT_STAMP)
$(BUILD)/src/util/version.o $(BUILD)/pic/src/util/version.o: override CFLAGS += -DWF_GIT_HASH='"$(GIT_HASH)"'

# The 4- and 8-lane noise kernels (AVX, AVX-512) and the 8- and 16-lane Philox (AVX2, AVX-512): called only on
# CPUs that have them (src/core/rng.c checks at run time).
ifneq ($(filter x86_64%,$(shell $(CC) -dumpmachine)),)
$(BUILD)/src/core/noise_avx.o: override CFLAGS += -mavx
$(BUILD)/src/core/philox_avx2.o: override CFLAGS += -mavx2
$(BUILD)/src/core/noise_avx512.o $(BUILD)/src/core/philox_avx512.o: override CFLAGS += -mavx512f
endif

$(LIBA): $(LIB_OBJ)
	@mkdir -p $(dir $@)
	rm -f $@
	ar rcs $@ $^

$(BIN): $(CLI_OBJ) $(LIBA)
	@mkdir -p $(dir $@)
	$(CC) $(LDFLAGS) $(CLI_OBJ) $(LIBA) $(LDLIBS) -o $@

$(BUILD)/tests/%: $(BUILD)/tests/%.o $(LIBA)
	$(CC) $(LDFLAGS) $< $(LIBA) $(LDLIBS) -o $@

$(BUILD)/bench/%: $(BUILD)/bench/%.o $(LIBA)
	$(CC) $(LDFLAGS) $< $(LIBA) $(LDLIBS) -o $@

$(BUILD)/tools/%: $(BUILD)/tools/%.o $(LIBA)
	$(CC) $(LDFLAGS) $< $(LIBA) $(LDLIBS) -o $@

$(BUILD)/fuzz/%_replay: $(BUILD)/fuzz/fuzz_%.o $(BUILD)/fuzz/replay_main.o $(LIBA)
	$(CC) $(LDFLAGS) $(filter %.o,$^) $(LIBA) $(LDLIBS) -o $@

$(BUILD)/fuzz/%_fuzzer: $(BUILD)/fuzz/fuzz_%.o $(LIBA)
	$(CC) $(LDFLAGS) -fsanitize=fuzzer $< $(LIBA) $(LDLIBS) -o $@

# Example controller plugins (docs/controllers.md): shared libraries for `model: plugin`, tested by make test.
$(BUILD)/plugins/%.so: examples/plugins/%.c include/wavefuel/cf_plugin.h
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS) -fPIC -shared $< -o $@

tests: $(BIN) $(TEST_BIN) $(REPLAY_BIN) $(PLUGIN_SO) $(TOOL_BIN)

# The Python package (docs/python.md): lib/libwavefuel.so, the library's objects compiled again with -fPIC in
# $(BUILD)/pic (bin/wavefuel and lib/libwavefuel.a are built as before), linked with the same libraries, and a copy
# next to the package so that `pip install ./python` ships it.
PIC_OBJ  := $(LIB_SRC:%.c=$(BUILD)/pic/%.o)
LIBSO    := lib/libwavefuel.so
$(BUILD)/pic/%.o: %.c Makefile
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS) -fPIC -c $< -o $@
ifneq ($(filter x86_64%,$(shell $(CC) -dumpmachine)),)
$(BUILD)/pic/src/core/noise_avx.o: override CFLAGS += -mavx
$(BUILD)/pic/src/core/philox_avx2.o: override CFLAGS += -mavx2
$(BUILD)/pic/src/core/noise_avx512.o $(BUILD)/pic/src/core/philox_avx512.o: override CFLAGS += -mavx512f
endif
$(LIBSO): $(PIC_OBJ)
	@mkdir -p $(dir $@)
	$(CC) -shared $(LDFLAGS) $(PIC_OBJ) $(LDLIBS) -o $@
python/wavefuel/libwavefuel.so: $(LIBSO)
	cp $< $@
python: python/wavefuel/libwavefuel.so
fuzzers: $(FUZZER_BIN)
.SECONDARY: $(FUZZ_TARGETS:%=$(BUILD)/fuzz/fuzz_%.o) $(BUILD)/fuzz/replay_main.o
bench: $(BIN) $(BENCH_BIN)

# The README's two commands.
run: deps
	@$(MAKE) --no-print-directory all
	./tools/run-default.sh

test: deps
	@$(MAKE) --no-print-directory tests python
	@BUILD=$(BUILD) ./tests/run.sh

check: test

# Address + undefined-behaviour sanitizers over the whole suite, in a separate build tree.
sanitize: deps
	@$(MAKE) --no-print-directory BUILD=build-san CFLAGS="-O1 -g -fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined" \
	    LDFLAGS="-fsanitize=address,undefined" BIN=build-san/bin/wavefuel LIBA=build-san/lib/libwavefuel.a tests
	@BUILD=build-san WAVEFUEL_BIN=build-san/bin/wavefuel ASAN_OPTIONS=detect_leaks=1 ./tests/run.sh

# libFuzzer (clang, address + undefined) on every fuzz target for FUZZ_SECONDS each; fuzz-smoke: 10 s each.
# New crashes are saved into fuzz/crashes/TARGET/, where the test suite replays them. See fuzz/README.md.
fuzz:
	@FUZZ_SECONDS=$(FUZZ_SECONDS) ./fuzz/run.sh

fuzz-smoke:
	@FUZZ_SECONDS=10 ./fuzz/run.sh

# ThreadSanitizer over the OpenMP code: clang + LLVM's libomp with its Archer tool (docs/reliability.md).
tsan:
	@./tools/tsan-tests.sh

# valgrind --leak-check=full on every test binary and one full run (docs/reliability.md).
valgrind:
	@$(MAKE) --no-print-directory tests
	@./tools/valgrind-tests.sh

# MPI driver (docs/sweeps.md, docs/mpi.md): bin/wavefuel-mpi = src/mpi/*.c + src/cli/cmd_{sweep,run}.c built with -DWF_MPI by
# mpicc in $(BUILD)/mpi, linked with the library. Optional: needs `tools/install-deps.sh mpi`; `make` never does.
MPICC    ?= mpicc
MPI_OBJ  := $(patsubst %.c,$(BUILD)/mpi/%.o,$(sort $(wildcard src/mpi/*.c)) src/cli/cmd_sweep.c src/cli/cmd_run.c) \
            $(patsubst %,$(BUILD)/src/cli/%.o,fail process options run_output resume_target progress)
.PHONY: mpi
mpi: bin/wavefuel-mpi
$(BUILD)/mpi/%.o: %.c Makefile
	@mkdir -p $(dir $@)
	$(MPICC) $(CFLAGS) -DWF_MPI -c $< -o $@
bin/wavefuel-mpi: $(MPI_OBJ) $(LIBA)
	@mkdir -p $(dir $@)
	$(MPICC) $(LDFLAGS) $(MPI_OBJ) $(LIBA) $(LDLIBS) -o $@
-include $(MPI_OBJ:.o=.d)

# `make install PREFIX=DIR` (docs/install.md): the program, the library and its headers, a pkg-config file, the
# vehicle classes, the example scenarios and, when DATA names a directory with cycles/, the drive cycles (they are
# not part of the repository). An installed PREFIX/bin/wavefuel finds PREFIX/share/wavefuel/vehicles and .../data
# itself (src/cli/process.c), from any working directory. DESTDIR is prepended for staged installs.
PREFIX   ?= /usr/local
DATA     ?= ../shared/data
WF_VERSION := $(shell sed -n 's/^\#define WF_VERSION "\(.*\)"/\1/p' include/wavefuel/version.h)
SHARE    := $(DESTDIR)$(PREFIX)/share/wavefuel
.PHONY: install
install: $(BIN) $(LIBA)
	install -d $(DESTDIR)$(PREFIX)/bin $(DESTDIR)$(PREFIX)/lib/pkgconfig $(DESTDIR)$(PREFIX)/include/wavefuel \
	    $(SHARE)/vehicles $(SHARE)/scenarios/data
	install -m 755 $(BIN) $(DESTDIR)$(PREFIX)/bin/wavefuel
	install -m 644 $(LIBA) $(DESTDIR)$(PREFIX)/lib/libwavefuel.a
	install -m 644 include/wavefuel/*.h $(DESTDIR)$(PREFIX)/include/wavefuel/
	install -m 644 vehicles/*.yaml $(SHARE)/vehicles/
	install -m 644 scenarios/*.yaml $(SHARE)/scenarios/
	install -m 644 scenarios/data/* $(SHARE)/scenarios/data/
	@if [ -d "$(DATA)/cycles" ]; then install -d $(SHARE)/data/cycles && \
	    install -m 644 $(DATA)/cycles/* $(SHARE)/data/cycles/ && echo "installed the drive cycles of $(DATA)"; \
	else echo "no $(DATA)/cycles: drive cycles not installed (give DATA=DIR, or \$$WAVEFUEL_DATA at run time)"; fi
	printf '%s\n' 'prefix=$(PREFIX)' 'libdir=$${prefix}/lib' 'includedir=$${prefix}/include' '' \
	    'Name: wavefuel' 'Description: CIRCLES vehicle energy models and traffic energy simulation' \
	    'Version: $(WF_VERSION)' 'Cflags: -I$${includedir}' \
	    'Libs: -L$${libdir} -lwavefuel $(filter -fopenmp,$(LDFLAGS)) $(LDLIBS)' \
	    > $(DESTDIR)$(PREFIX)/lib/pkgconfig/wavefuel.pc

clean:
	rm -rf $(BUILD) build-san build-fuzz build-tsan bin lib python/wavefuel/libwavefuel.so

-include $(LIB_OBJ:.o=.d) $(PIC_OBJ:.o=.d) $(CLI_OBJ:.o=.d) $(TEST_BIN:=.d) $(BENCH_BIN:=.d)
-include $(FUZZ_TARGETS:%=$(BUILD)/fuzz/fuzz_%.d) $(BUILD)/fuzz/replay_main.d
