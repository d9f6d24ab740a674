/* First touch of large arrays, and giving pages back (mem.h). */
#define _DEFAULT_SOURCE
#include "util/mem.h"

#include <stdint.h>
#include <sys/mman.h>
#include <unistd.h>

#ifndef MADV_POPULATE_WRITE
#define MADV_POPULATE_WRITE 23 /* Linux 5.14; older kernels answer EINVAL, which is ignored */
#endif

#define CUT_BYTES ((uintptr_t)2 << 20)

/* The k-th of `parts` cut points of [lo, hi) (k in 1 .. parts), at a 2 MiB-aligned address: a part boundary never
 * falls inside a page of any size this kernel maps. */
static uintptr_t cut(uintptr_t lo, uintptr_t hi, int k, int parts)
{
    if (k >= parts) return hi;
    uintptr_t c = (lo + (hi - lo) / (uintptr_t)parts * (uintptr_t)k + CUT_BYTES - 1) & ~(CUT_BYTES - 1);
    return c > hi ? hi : c;
}

void wf_mem_prefault(void *p, size_t bytes, int part, int parts)
{
    if (!p || !bytes || part < 0 || part >= parts) return;
    uintptr_t page = (uintptr_t)sysconf(_SC_PAGESIZE);
    /* the pages that hold the range: writing into them is what the step would do first */
    uintptr_t lo = (uintptr_t)p & ~(page - 1), hi = ((uintptr_t)p + bytes + page - 1) & ~(page - 1);
    uintptr_t a = part ? cut(lo, hi, part, parts) : lo, b = cut(lo, hi, part + 1, parts);
    if (b > a) (void)madvise((void *)a, b - a, MADV_POPULATE_WRITE);
}

void wf_mem_release(void *p, size_t bytes)
{
    if (!p || !bytes) return;
    uintptr_t page = (uintptr_t)sysconf(_SC_PAGESIZE);
    uintptr_t lo = ((uintptr_t)p + page - 1) & ~(page - 1), hi = ((uintptr_t)p + bytes) & ~(page - 1);
    if (hi > lo) (void)madvise((void *)lo, hi - lo, MADV_DONTNEED);
}
