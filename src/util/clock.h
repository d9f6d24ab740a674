/* The one wall clock of wavefuel: seconds from a monotonic clock, for wall times, progress and checkpoint
 * intervals (never for results). Internal to wavefuel. */
#ifndef WAVEFUEL_CLOCK_H
#define WAVEFUEL_CLOCK_H

/* Seconds since an arbitrary fixed origin (CLOCK_MONOTONIC: never jumps with the date); differences are
 * elapsed wall time. Thread-safe. */
double wf_wall_now(void);

/* Seconds of CPU time the process has used, all its threads summed (CLOCK_PROCESS_CPUTIME_ID: a system call, some
 * 0.3 us; the thread governor reads it twice per stretch of steps). */
double wf_cpu_now(void);

/* Sleep about ms milliseconds (the polling loops of the sweep scheduler and the MPI workers: 1 ms keeps a waiting
 * thread off the CPU). */
void wf_sleep_ms(long ms);

#endif
