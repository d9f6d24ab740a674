/* The one choice of SIMD level (simd.h): the CPU's widest, or at most 2 or 4 lanes when WAVEFUEL_SIMD=2 or 4.
 * Kernels ask here instead of reading the environment or the CPU themselves. */
#include "core/simd.h"

#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

static WfSimdLevel detect(void)
{
    WfSimdLevel cap = WF_SIMD_AVX512;
    const char *force = getenv("WAVEFUEL_SIMD");
    if (force && strcmp(force, "2") == 0) cap = WF_SIMD_BASE;
    if (force && strcmp(force, "4") == 0) cap = WF_SIMD_AVX2;
    WfSimdLevel cpu = WF_SIMD_BASE;
#if defined(__x86_64__) && defined(__GNUC__)
    /* x86-64-v4's AVX-512 subsets, as the x86-64-v4 clones require (libgcc also checks that the OS saves the
     * registers). */
    if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq") &&
        __builtin_cpu_supports("avx512vl") && __builtin_cpu_supports("avx512bw"))
        cpu = WF_SIMD_AVX512;
    else if (__builtin_cpu_supports("avx2"))
        cpu = WF_SIMD_AVX2;
    else if (__builtin_cpu_supports("avx"))
        cpu = WF_SIMD_AVX;
#endif
    return cpu < cap ? cpu : cap;
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
