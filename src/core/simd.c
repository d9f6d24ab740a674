/* The one choice of SIMD level (simd.h): the CPU's widest, or 2 lanes when WAVEFUEL_SIMD=2. Kernels ask here
 * instead of reading the environment or the CPU themselves. */
#include "core/simd.h"

#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

static WfSimdLevel detect(void)
{
    const char *force = getenv("WAVEFUEL_SIMD");
    if (force && strcmp(force, "2") == 0) return WF_SIMD_BASE;
#if defined(__x86_64__) && defined(__GNUC__)
    if (__builtin_cpu_supports("avx2")) return WF_SIMD_AVX2;
    if (__builtin_cpu_supports("avx")) return WF_SIMD_AVX;
#endif
    return WF_SIMD_BASE;
}

WfSimdLevel wf_simd_level(void)
{
    /* -1: not decided yet. Two threads deciding at once store the same answer, so a relaxed atomic suffices. */
    static _Atomic int level = -1;
    int l = atomic_load_explicit(&level, memory_order_relaxed);
    if (l < 0) {
        l = (int)detect();
        atomic_store_explicit(&level, l, memory_order_relaxed);
    }
    return (WfSimdLevel)l;
}
