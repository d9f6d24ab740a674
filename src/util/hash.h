/* FNV-1a, 64 bit (Fowler, Noll, Vo): a checksum of byte strings, for detecting damaged files (tables,
 * checkpoints) and naming runs; not a cryptographic hash. Internal to wavefuel. */
#ifndef WAVEFUEL_HASH_H
#define WAVEFUEL_HASH_H

#include <stddef.h>
#include <stdint.h>

#define WF_FNV1A64_INIT 0xcbf29ce484222325ULL

/* Continue the hash h (start with WF_FNV1A64_INIT) over n bytes at p. */
static inline uint64_t wf_fnv1a64(uint64_t h, const void *p, size_t n)
{
    const unsigned char *b = p;
    for (size_t i = 0; i < n; i++) h = (h ^ b[i]) * 0x100000001b3ULL;
    return h;
}

#endif
