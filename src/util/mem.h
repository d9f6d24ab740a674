/* First touch of the large per-vehicle arrays, and giving back the pages of those a process has done with. Internal
 * to wavefuel.
 *
 * A road of 10^7 vehicles keeps some 2 GB of arrays. The step's sums are first touched by `+=`: each 4 KiB page is
 * then mapped to the shared zero page on the read and faults again, copy-on-write, on the write, with the other
 * threads' TLB entries flushed; at 10^7 vehicles that took 2.5-3 s of the first steps on this project's machine.
 * Taking the pages writable when the run is created, split between the threads, brought the whole run of 48 steps
 * on two threads from 13.7 to 11.9 s (bench/README.md, "Session 18: first touch of the step's arrays"). The call is
 * advice: where the kernel refuses it (before Linux 5.14) the pages are taken by the step as before, and no value
 * ever changes. */
#ifndef WAVEFUEL_MEM_H
#define WAVEFUEL_MEM_H

#include <stddef.h>
#include <stdlib.h>

/* Take now, writable, the pages of [p, p + bytes) not yet in memory (madvise MADV_POPULATE_WRITE), without
 * changing their contents: part `part` of `parts` of them, cut at 2 MiB-aligned addresses, so that threads taking
 * the parts at once share no page (the kernel's clearing of new pages is then split between them). */
void wf_mem_prefault(void *p, size_t bytes, int part, int parts);

/* Give back the pages wholly inside [p, p + bytes) (madvise MADV_DONTNEED): they read as zeros afterwards. The
 * pages at either end, which may hold bytes outside the range, are kept. */
void wf_mem_release(void *p, size_t bytes);

/* Free each pointer in turn, in the order given (NULL is skipped by free): a destroy function's arrays in one
 * statement. A const pointer needs a (void *) cast. */
#define WF_FREE(...)                                                                                           \
    do {                                                                                                       \
        void *wf_free_[] = {__VA_ARGS__};                                                                      \
        for (size_t wf_i_ = 0; wf_i_ < sizeof wf_free_ / sizeof wf_free_[0]; wf_i_++) free(wf_free_[wf_i_]);   \
    } while (0)

#endif
