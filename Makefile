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
CFLAGS   += -std=c11 -D_GNU_SOURCE -Wall -Wextra -Wpedantic -Wshadow -Wstrict-prototypes \
            -ffp-contract=off -fno-fast-math -Iinclude -Isrc $(HDF5_CFLAGS) -MMD -MP \
            -DWF_GIT_HASH='"$(GIT_HASH)"' -DWF_REPO_DIR='"$(CURDIR)"'
ifeq ($(WERROR),1)
CFLAGS   += -Werror
endif
ifeq ($(OPENMP),1)
CFLAGS   += -fopenmp
LDFLAGS  += -fopenmp
endif
LDLIBS   += $(HDF5_LIBS) -lsundials_cvodes -lsundials_arkode -lsundials_nvecserial -lsundials_nvecopenmp \
            -lsundials_generic -lyaml -lm

LIB_SRC  := $(sort $(wildcard src/*.c src/*/*.c))
LIB_SRC  := $(filter-out src/main.c src/cli/%,$(LIB_SRC))
CLI_SRC  := src/main.c $(sort $(wildcard src/cli/*.c))
TEST_SRC := $(sort $(wildcard tests/test_*.c))
BENCH_SRC:= $(sort $(wildcard bench/*.c))
LIB_OBJ  := $(LIB_SRC:%.c=$(BUILD)/%.o)
CLI_OBJ  := $(CLI_SRC:%.c=$(BUILD)/%.o)
TEST_BIN := $(TEST_SRC:tests/%.c=$(BUILD)/tests/%)
BENCH_BIN:= $(BENCH_SRC:bench/%.c=$(BUILD)/bench/%)
LIBA     := lib/libwavefuel.a
BIN      := bin/wavefuel

.PHONY: all run test check sanitize deps clean bench tests
all: $(BIN) $(LIBA)

deps:
	@./tools/install-deps.sh

$(BUILD)/%.o: %.c
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS) -c $< -o $@

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

tests: $(BIN) $(TEST_BIN)
bench: $(BIN) $(BENCH_BIN)

# The README's two commands.
run: deps
	@$(MAKE) --no-print-directory all
	./tools/run-default.sh

test: deps
	@$(MAKE) --no-print-directory tests
	@BUILD=$(BUILD) ./tests/run.sh

check: test

# Address + undefined-behaviour sanitizers over the whole suite, in a separate build tree.
sanitize: deps
	@$(MAKE) --no-print-directory BUILD=build-san CFLAGS="-O1 -g -fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined" \
	    LDFLAGS="-fsanitize=address,undefined" BIN=build-san/bin/wavefuel LIBA=build-san/lib/libwavefuel.a tests
	@BUILD=build-san WAVEFUEL_BIN=build-san/bin/wavefuel ASAN_OPTIONS=detect_leaks=1 ./tests/run.sh

clean:
	rm -rf $(BUILD) build-san bin lib

-include $(LIB_OBJ:.o=.d) $(CLI_OBJ:.o=.d) $(TEST_BIN:=.d) $(BENCH_BIN:=.d)
