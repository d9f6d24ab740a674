/* The network behind include/wavefuel/mlp.h: its layers as the loader (src/io/h5mlp.c) fills them and the
 * evaluator (src/models/cf/mlp.c) reads them. Internal (not installed). */
#ifndef WAVEFUEL_MODELS_CF_MLP_H
#define WAVEFUEL_MODELS_CF_MLP_H

#include "wavefuel/cf.h"
#include "wavefuel/mlp.h"

typedef enum { WF_MLP_IDENTITY = 0, WF_MLP_TANH = 1, WF_MLP_RELU = 2 } WfMlpAct;
/* As written in the file's `activation` and `output/kind` datasets, indexed by WfMlpAct and WfMlpOutput;
 * NULL-terminated. */
extern const char *const wf_mlp_act_names[];
extern const char *const wf_mlp_output_names[];

typedef struct WfMlpLayer {
    size_t   n_in, n_out;
    double  *w;      /* owned: n_out x n_in, row-major (PyTorch's Linear.weight), y = act(w x + b) */
    double  *b;      /* owned: n_out */
    WfMlpAct act;
} WfMlpLayer;

struct WfMlp {
    char        path[1024];
    size_t      n_layers;
    WfMlpLayer  layer[WF_MLP_MAX_LAYERS];
    double      in_mean[WF_MLP_INPUTS], in_std[WF_MLP_INPUTS]; /* units of the inputs; std > 0 */
    double      out_scale, out_offset, out_min, out_max;        /* min/max: -inf/+inf when not given */
    WfMlpOutput output;
    WfCfModel   model;                                          /* set by wf_mlp_init_model */
};

/* After the loader filled the layers and the output kind: the group model (wf_mlp_model). */
void wf_mlp_init_model(WfMlp *net);

#endif
