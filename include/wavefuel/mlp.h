/* Learned controllers: a feed-forward network (multilayer perceptron) read from an HDF5 file in the format of
 * docs/controllers.md ("mlp: learned controllers"), evaluated for the vehicles of a `model: mlp` driver group as one
 * batch per step. Input: the group's observation rows, [own speed m/s, leader speed m/s, bumper-to-bumper gap m]
 * (wf_sim_observe), normalised as (x - mean) / std; hidden layers y = act(W x + b); output y * scale + offset,
 * clipped to [min, max], is an acceleration (m/s^2) or a set speed (m/s, followed by the acc law). */
#ifndef WAVEFUEL_MLP_H
#define WAVEFUEL_MLP_H

#include <stddef.h>
#include "wavefuel/err.h"

#define WF_MLP_INPUTS     3    /* the observation row: own speed, leader speed, gap */
#define WF_MLP_MAX_LAYERS 16
#define WF_MLP_MAX_WIDTH  1024 /* units of one layer */

typedef struct WfMlp WfMlp;
struct WfCfModel;

/* What the network's output commands. */
typedef enum { WF_MLP_ACCELERATION = 0, WF_MLP_SPEED = 1 } WfMlpOutput;

/* Read and check a network file (src/io/h5mlp.c). Fails with WF_EINPUT and a message naming the file and the
 * dataset when the file is not HDF5, a dataset is missing or of the wrong type or shape (the first layer must take
 * WF_MLP_INPUTS inputs, each layer the previous one's outputs, the last give one output), a value is NaN or
 * infinite, a std is not positive, min >= max, or an activation or output kind is unknown; WF_ESYS on a failed
 * read or allocation. Ownership: *out is the caller's until wf_mlp_destroy(); NULL on failure; path is copied. */
int  wf_mlp_load(const char *path, WfMlp **out, WfError *err);
void wf_mlp_destroy(WfMlp **net); /* accepts NULL and clears the pointer */

/* Evaluate the network on n rows of WF_MLP_INPUTS doubles (row-major), writing n outputs (the command, after
 * scaling and clipping). Each output depends only on its row, with a fixed order of operations: the same bits for
 * any n, any position of the row in the batch and any thread count (nthreads > 1 splits the rows among an OpenMP
 * team when n is large). Allocates nothing. Non-finite inputs give non-finite outputs; the caller checks. */
void wf_mlp_eval(const WfMlp *net, const double *rows, size_t n, double *out, int nthreads);

WfMlpOutput wf_mlp_output(const WfMlp *net);
const char *wf_mlp_path(const WfMlp *net);
/* The driver-group model of a `model: mlp` group: `external` (acceleration) or `external_speed` (set speed) under
 * the name "mlp", with the acc keys as parameters (src/models/cf/external.c). Valid until wf_mlp_destroy(). */
const struct WfCfModel *wf_mlp_model(const WfMlp *net);

#endif
