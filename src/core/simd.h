/* SIMD: the one choice of vector width for the whole library, and the clone attribute of hot loops.
 * WF_SIMD_CLONES before a hot loop's function: GCC builds it twice, for baseline x86-64 and for AVX2, and the
 * loader picks the one the CPU runs (function multi-versioning), so its loops vectorise 4 doubles wide where AVX2
 * exists while the binary still runs everywhere. The arithmetic is lane-wise IEEE either way and contraction into
 * FMA is off project-wide, so both versions give the same bits (tests/t_simd.sh compares whole runs). Not under
 * clang (fuzz and TSan builds) or AddressSanitizer, where the plain function is built. */
#ifndef WAVEFUEL_SIMD_H
#define WAVEFUEL_SIMD_H

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__SANITIZE_ADDRESS__)
#define WF_SIMD_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define WF_SIMD_CLONES
#endif

/* Instruction sets the hand-written kernels (noise, CIRCLES energy) choose between, in increasing width. */
typedef enum { WF_SIMD_BASE = 0, WF_SIMD_AVX = 1, WF_SIMD_AVX2 = 2 } WfSimdLevel;

/* The widest level this CPU runs, decided on the first call and the same for the life of the process (every
 * kernel uses this one answer). The environment variable WAVEFUEL_SIMD=2 (2 lanes) caps it at WF_SIMD_BASE, so
 * that tests can compare the narrow kernels with the wide ones on one machine; it is read on that first call
 * only. Thread-safe; the kernels' results are the same bits at every level. */
WfSimdLevel wf_simd_level(void);

#endif
