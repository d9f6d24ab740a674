/* First touch of the per-vehicle arrays (src/util/mem.h). wf_mem_prefault takes exactly the pages of its range, in
 * parts cut at 2 MiB-aligned addresses, and keeps their contents; a ring's creation takes the pages of the sums its
 * step adds to (the step would first read them: zero page, then a second fault), and a process stepping a share of a
 * split ring takes only its share's (docs/mpi.md, Memory). Residency is read with mincore(2) on fresh anonymous
 * memory: the allocator's threshold is pinned so that the fleet's arrays are their own mappings, untouched by
 * calloc. */
#define _DEFAULT_SOURCE
#include <errno.h>
#include <malloc.h>
#include <stdint.h>
#include <sys/mman.h>

#include "wavefuel/engine.h"
#include "wavefuel/fleet.h"
#include "wavefuel/partition.h"
#include "wavefuel/scenario.h"
#include "wavefuel/stats.h"
#include "util/mem.h"
#include "wf_test.h"

#ifndef MADV_POPULATE_WRITE
#define MADV_POPULATE_WRITE 23
#endif

static size_t page_bytes(void) { return (size_t)sysconf(_SC_PAGESIZE); }

/* Pages [first, first + n) of the mapping at base resident: 1 each in in[]. */
static void resident(unsigned char *base, size_t first, size_t n, unsigned char *in)
{
    if (mincore(base + first * page_bytes(), n * page_bytes(), in)) memset(in, 0xff, n);
    for (size_t k = 0; k < n; k++) in[k] &= 1;
}

/* Whether this kernel takes pages on MADV_POPULATE_WRITE (Linux 5.14): the calls are advice and change nothing
 * elsewhere, so the cases below have nothing to check there. */
static int populate_supported(void)
{
    size_t pg = page_bytes();
    void *p = mmap(NULL, pg, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (p == MAP_FAILED) return 0;
    int ok = madvise(p, pg, MADV_POPULATE_WRITE) == 0 || errno != EINVAL;
    munmap(p, pg);
    if (!ok) printf("  MADV_POPULATE_WRITE is not supported by this kernel: nothing to check\n");
    return ok;
}

/* Parts 0..2 of a range that starts and ends inside pages: each part a run of whole pages beginning at the range's
 * first page or at a 2 MiB-aligned address, together exactly the range's pages, contents kept. */
static void test_prefault_parts(void)
{
    if (!populate_supported()) return;
    size_t pg = page_bytes(), span = (size_t)24 << 20, np = span / pg;
    unsigned char *map = mmap(NULL, span, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    CHECK(map != MAP_FAILED, "mmap of %zu bytes", span);
    if (map == MAP_FAILED) return;
    /* 4 KiB pages whatever the system's transparent huge pages: a huge page would take the range's neighbours too */
    (void)madvise(map, span, MADV_NOHUGEPAGE);
    unsigned char *in = malloc(np);
    /* the range: from 100 bytes into page 3 to 200 bytes into page 3 + 9 MiB / pg */
    size_t off = 3 * pg + 100, bytes = ((size_t)9 << 20) + 100, p0 = off / pg, p1 = (off + bytes - 1) / pg + 1;
    map[off + 5 * pg] = 42; /* a page already taken, with a value the call must keep */
    size_t done = 0;
    for (int part = 0; part < 3; part++) {
        wf_mem_prefault(map + off, bytes, part, 3);
        resident(map, 0, np, in);
        size_t n_in = 0, first = np, last = 0;
        for (size_t k = 0; k < np; k++)
            if (in[k]) n_in++, first = k < first ? k : first, last = k;
        CHECK(first >= p0 && last < p1, "part %d: pages [%zu, %zu] resident, the range is [%zu, %zu)", part, first,
              last, p0, p1);
        CHECK(n_in == last - first + 1, "part %d: the resident pages are not one run", part);
        if (part) { /* a part after the first begins where the previous ended, at a 2 MiB-aligned address */
            uintptr_t a = (uintptr_t)(map + (p0 + done) * pg);
            CHECK(a % ((uintptr_t)2 << 20) == 0, "part %d begins at %#lx, not 2 MiB-aligned", part, (unsigned long)a);
        }
        done = last - p0 + 1;
    }
    resident(map, 0, np, in);
    size_t bad = 0;
    for (size_t k = 0; k < np; k++) bad += in[k] != (k >= p0 && k < p1);
    CHECK(bad == 0, "%zu pages resident outside the range or not inside it", bad);
    size_t nonzero = 0;
    for (size_t k = 0; k < span; k++) nonzero += map[k] != 0;
    CHECK(map[off + 5 * pg] == 42 && nonzero == 1, "contents changed: %zu bytes not zero", nonzero);
    free(in);
    munmap(map, span);
}

/* A ring of 100 000 vehicles with noise and two classes: every per-vehicle sum of its step resident right after
 * creation, before any step; split in three, the middle share's sums alone, and its positions and speeds (the
 * fleet's build writes no other share's). */
static const char *ring_yaml =
    "seed: 3\n"
    "road: {length_m: 2500000}\n"
    "time: {duration_s: 1, dt_s: 0.1, output_interval_s: 0.1, warmup_s: 0}\n"
    "fleet:\n  vehicles: 100000\n  placement: random\n"
    "  classes:\n    - {class: midsize_sedan, fraction: 0.9}\n    - {class: class8_tractor, fraction: 0.1}\n"
    "  drivers:\n    - {model: idm, fraction: 1.0, noise_mps2: 0.1}\n"
    "initial: {state: equilibrium}\n";

/* Pages of vehicles [lo, hi) of array a (stride bytes a vehicle) resident; *outside: resident pages of the array's
 * other vehicles that share no page with [lo, hi), but the first (the allocator writes its header there). */
static size_t pages_in(const void *a, size_t stride, size_t n, size_t lo, size_t hi, size_t *missing, size_t *outside)
{
    size_t pg = page_bytes();
    uintptr_t base = (uintptr_t)a & ~(uintptr_t)(pg - 1), end = (uintptr_t)a + n * stride;
    size_t np = (end - base + pg - 1) / pg, in_range = 0;
    unsigned char *in = malloc(np);
    resident((unsigned char *)base, 0, np, in);
    size_t q0 = ((uintptr_t)a + lo * stride - base) / pg, q1 = ((uintptr_t)a + hi * stride - 1 - base) / pg + 1;
    *missing = *outside = 0;
    for (size_t k = 0; k < np; k++) {
        int inside = k >= q0 && k < q1;
        in_range += inside;
        if (inside && !in[k]) (*missing)++;
        if (!inside && in[k] && k) (*outside)++;
    }
    free(in);
    return in_range;
}

static int no_call(void *ctx, WfError *err) { (void)ctx, (void)err; return 0; }

/* A rank alone: every collective of the fleet's build answers as if the other ranks had added nothing to it (which
 * pages a share takes is checked here, not its values, which tests/test_partition.c and tests/t_mpi.sh check). */
static int alone_chain(void *ctx, void *buf, size_t bytes, void (*fn)(void *, void *), void *arg, WfError *err)
{
    (void)ctx, (void)bytes, (void)err;
    fn(arg, buf);
    return 0;
}
static int alone_gather(void *ctx, void *buf, const size_t *off, int root, WfError *err)
{
    (void)ctx, (void)buf, (void)off, (void)root, (void)err;
    return 0;
}
static int alone_sum_f64(void *ctx, double *v, size_t m, WfError *err)
{
    (void)ctx, (void)v, (void)m, (void)err;
    return 0;
}
static int alone_allgather(void *ctx, const void *mine, void *all, size_t bytes, WfError *err)
{
    (void)err;
    for (int r = 0; r < *(const int *)ctx; r++) memcpy((char *)all + (size_t)r * bytes, mine, bytes);
    return 0;
}

/* Whether calloc leaves the pages of an array of `bytes` untouched (glibc's mappings do; a sanitizer's allocator may
 * clear or reuse them): only then can pages outside a share show what the run took. */
static int calloc_untouched(size_t bytes)
{
    size_t pg = page_bytes(), np = bytes / pg;
    unsigned char *a = calloc(bytes, 1), *in = malloc(np);
    size_t taken = 0;
    if (a && in) {
        uintptr_t base = ((uintptr_t)a + pg - 1) & ~(uintptr_t)(pg - 1);
        resident((unsigned char *)base, 0, np - 1, in);
        for (size_t k = 0; k + 1 < np; k++) taken += in[k];
    }
    free(a), free(in);
    if (taken) printf("  this allocator touches calloc'd memory: pages outside a share are not checked\n");
    return a && !taken;
}

static void check_share(const char *what, int size, int rank, int check_outside)
{
    char dir[] = "/tmp/wf_mem_XXXXXX", path[64];
    WfError err = {0};
    WfScenario *sc = NULL;
    WfSim *sim = NULL;
    volatile sig_atomic_t own = 0;
    WfPartition part = {.rank = rank, .size = size, .ctx = &size, .wait_next = no_call, .chain = alone_chain,
                        .gather = alone_gather, .sum_f64 = alone_sum_f64, .allgather = alone_allgather,
                        .stop_own = &own};
    const char *p = wf_test_write_yaml(ring_yaml, dir, path, sizeof path);
    int rc = p ? wf_scenario_load(p, NULL, 0, &sc, &err) : -1;
    if (!rc) rc = wf_sim_create_part(sc, size > 1 ? &part : NULL, &sim, &err);
    CHECK(rc == 0, "%s: %s", what, err.msg);
    if (!rc) {
        const WfFleet *f = wf_sim_fleet(sim);
        size_t n = f->n, b0, b1, nb = (n + WF_STATS_BLOCK - 1) / WF_STATS_BLOCK;
        wf_partition_blocks(nb, size, rank, &b0, &b1);
        size_t lo = b0 * WF_STATS_BLOCK, hi = b1 * WF_STATS_BLOCK < n ? b1 * WF_STATS_BLOCK : n;
        struct { const char *name; const void *a; size_t stride; } sums[] = {
            {"fuel_g", f->fuel_g, sizeof *f->fuel_g}, {"sum_v", f->sum_v, sizeof *f->sum_v},
            {"sum_a2", f->sum_a2, sizeof *f->sum_a2}, {"stopped_steps", f->stopped_steps, sizeof *f->stopped_steps},
            {"hard_brakes", f->hard_brakes, sizeof *f->hard_brakes}};
        for (size_t j = 0; j < sizeof sums / sizeof *sums; j++) {
            size_t missing, outside, pages = pages_in(sums[j].a, sums[j].stride, n, lo, hi, &missing, &outside);
            CHECK(missing == 0, "%s: %s: %zu of the share's %zu pages not taken at creation", what, sums[j].name,
                  missing, pages);
            CHECK(outside == 0 || !check_outside, "%s: %s: %zu pages outside the share [%zu, %zu) taken", what,
                  sums[j].name, outside, lo, hi);
        }
        /* The state the build writes (wf_fleet_create_part): the share's, and its last vehicle's leader (one more
         * page when the share ends at a page's end). */
        struct { const char *name; const void *a; size_t stride; } built[] = {
            {"x_m", f->x_m, sizeof *f->x_m}, {"v_mps", f->v_mps, sizeof *f->v_mps}};
        for (size_t j = 0; j < sizeof built / sizeof *built; j++) {
            size_t missing, outside;
            pages_in(built[j].a, built[j].stride, n, lo, hi, &missing, &outside);
            CHECK(outside <= 1 || !check_outside, "%s: %s: %zu pages outside the share [%zu, %zu) written", what,
                  built[j].name, outside, lo, hi);
        }
    }
    wf_sim_destroy(&sim);
    wf_scenario_destroy(&sc);
    if (p) wf_test_remove_yaml(dir, path);
}

static void test_ring_takes_its_share(void)
{
    if (!populate_supported()) return;
    int outside = calloc_untouched(100000 * sizeof(uint32_t)); /* the smallest of the sums checked */
    check_share("one process", 1, 0, outside);
    check_share("rank 1 of 3", 3, 1, outside);
}

int main(void)
{
    /* every calloc above 64 KiB a fresh mapping (no threshold raised by earlier frees): untouched until used */
    mallopt(M_MMAP_THRESHOLD, 64 * 1024);
    RUN(test_prefault_parts);
    RUN(test_ring_takes_its_share);
    TEST_EXIT();
}
