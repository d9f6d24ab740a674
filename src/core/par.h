/* WF_PAR_FOR(cond, "omp parallel for <clauses>", for-loop): runs the loop in an OpenMP team when `cond` holds and
 * as a plain loop otherwise, with the loop written once. libgomp enters its runtime (futex system calls, a team
 * barrier) even for `parallel for if (0)`, which costs more than the work of a small fleet at every step. */
#ifndef WAVEFUEL_PAR_H
#define WAVEFUEL_PAR_H

#ifdef _OPENMP
#define WF_PAR_FOR(cond, pragma, ...) \
    do {                              \
        if (cond) {                   \
            _Pragma(pragma) __VA_ARGS__ \
        } else {                      \
            __VA_ARGS__               \
        }                             \
    } while (0)
#else
#define WF_PAR_FOR(cond, pragma, ...) \
    do {                              \
        (void)sizeof(cond);           \
        __VA_ARGS__                   \
    } while (0)
#endif

#endif
