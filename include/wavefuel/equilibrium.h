/* Uniform-flow equilibria of car-following models, for initial conditions: the gap at which a model holds a
 * given speed, and the common speed at which a heterogeneous fleet exactly fills a ring. Root finding is
 * the Illinois variant of regula falsi on a bracket (monotone functions), deterministic and ~10-20 model
 * evaluations per root instead of ~60 for bisection. */
#ifndef WAVEFUEL_EQUILIBRIUM_H
#define WAVEFUEL_EQUILIBRIUM_H

#include <stddef.h>
#include "wavefuel/cf.h"
#include "wavefuel/fleet.h"
#include "wavefuel/partition.h"
#include "wavefuel/scenario.h"

/* Equilibrium bumper-to-bumper gap at speed v: the s in [0, s_max] with accel(s, v, v) = 0 (accel grows with
 * s). Returns 0 when the model accelerates even at s = 0, s_max when it still brakes at s_max. */
double wf_equilibrium_gap(const WfCfModel *m, const void *params, double v_mps, double s_max_m);

/* Common speed v* in [0, v_hi] with sum_i (s_e,i(v*) + length_i) = L for the fleet's drawn parameters;
 * writes each vehicle's gap s_e,i(v*) to gap_m (n entries). Parallel over vehicles; the sum runs in a fixed
 * order, so the result does not depend on the thread count. */
double wf_equilibrium_ring(const WfScenario *sc, const WfFleet *f, double v_hi_mps, double *gap_m);

/* The sum above runs over blocks of WF_EQ_BLOCK vehicles, each summed in ring order, then over the blocks in order. */
enum { WF_EQ_BLOCK = 4096 };

/* The same speed for a ring split across processes (wavefuel/partition.h): this process sums the blocks that start
 * among its vehicles [lo, hi), reading the gaps and parameters of up to WF_EQ_BLOCK - 1 vehicles past hi, and the
 * blocks' sums are added over the processes (each block is one process's: every process gets the same sums, so the
 * same speed, bit for bit, as one process). Collective. Writes gap_m only over those blocks; NAN with err set when it
 * fails. */
double wf_equilibrium_ring_part(const WfScenario *sc, const WfFleet *f, double v_hi_mps, const WfPartition *part,
                                size_t lo, size_t hi, double *gap_m, WfError *err);

/* The equilibrium gaps at speed v of vehicles [lo, hi) into gap_m[lo, hi) (what the functions above write). */
void wf_equilibrium_ring_gaps(const WfScenario *sc, const WfFleet *f, double v_mps, size_t lo, size_t hi,
                              double *gap_m);

#endif
