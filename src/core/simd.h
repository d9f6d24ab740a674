/* SIMD: the one choice of vector width for the whole library, and the clone attribute of hot loops.
 * WF_SIMD_CLONES before a hot loop's function: GCC builds it three times, for baseline x86-64, for AVX2 and for
 * x86-64-v4 (AVX-512F, BW, CD, DQ, VL), and the loader picks the widest the CPU runs (function multi-versioning),
 * so its loops vectorise 4 or 8 doubles wide where the CPU allows while the binary still runs everywhere. The
 * arithmetic is lane-wise IEEE in every version and contraction into FMA is off project-wide, so all give the same
 * bits (tests/t_simd.sh compares whole runs; the fingerprints were taken with the AVX2 versions). Not under clang
 * (fuzz and TSan builds) or AddressSanitizer, where the plain function is built. */
#ifndef WAVEFUEL_SIMD_H
#define WAVEFUEL_SIMD_H

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__SANITIZE_ADDRESS__)
#define WF_SIMD_CLONES __attribute__((target_clones("arch=x86-64-v4", "avx2", "default")))
#else
#define WF_SIMD_CLONES
#endif

/* Instruction sets the hand-written kernels (noise, CIRCLES energy) choose between, in increasing width:
 * 2 lanes (SSE2), 4 (AVX: noise; AVX2: energy), 8 (x86-64-v4). */
typedef enum { WF_SIMD_BASE = 0, WF_SIMD_AVX = 1, WF_SIMD_AVX2 = 2, WF_SIMD_AVX512 = 3 } WfSimdLevel;

/* The widest level this CPU runs, decided on the first call and the same for the life of the process (every
 * kernel uses this one answer). The environment variable WAVEFUEL_SIMD caps it, so that tests can compare the
 * narrow kernels with the wide ones on one machine: 2 (2 lanes) at WF_SIMD_BASE, 4 (4 lanes) at WF_SIMD_AVX2;
 * any other value leaves the CPU's level. It caps the hand-written kernels only, not the compiler's clones above,
 * which the loader chooses. Read on that first call only. Thread-safe; the kernels' results are the same bits at
 * every level. */
WfSimdLevel wf_simd_level(void);

#endif
