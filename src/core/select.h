/* Where one value occurs in a block of 16-bit ids (a class or a driver group): the gather step of the block kernel.
 * Internal (not installed). */
#ifndef WAVEFUEL_CORE_SELECT_H
#define WAVEFUEL_CORE_SELECT_H

#include <stddef.h>
#include <stdint.h>

/* Writes base + k for every k < m with id[k] == c, in increasing order, to idx (room for m entries; those past the
 * count may be overwritten) and returns their number. The same result at every SIMD level. */
size_t wf_select_eq16(const uint16_t *id, size_t m, uint16_t c, uint32_t base, uint32_t *idx);

#endif
