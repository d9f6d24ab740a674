/* WF_SIMD_CLONES before a hot loop's function: GCC builds it twice, for baseline x86-64 and for AVX2, and the
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

#endif
