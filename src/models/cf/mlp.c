/* Learned controllers (include/wavefuel/mlp.h): a feed-forward network evaluated on a batch of observation rows,
 *   x0 = (row - mean) / std,   x_{l+1} = act_l(W_l x_l + b_l),   command = clip(y * scale + offset, min, max)
 * with units those of the rows (m/s, m/s, m) and of the command (m/s^2 or m/s). The rows go through in blocks of
 * MLP_ROWS, laid out unit-major so the inner loop runs across the block's rows (vectorisable without reordering
 * any row's sum): every row's output comes from the same operations in the same order (each sum starts from the
 * bias and adds w_ji x_i for i = 0, 1, ...), whatever the block, the batch or the thread. */
#include "models/cf/mlp.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#if defined(__x86_64__)
#include <emmintrin.h>
#include <sleef.h>
#endif

#include "core/par.h"
#include "core/simd.h"

/* Rows of a block: 4 keeps the sums in registers (SSE2 pairs); blocks of 2 and 8 rows ran 1.4 and 2 times slower
 * on a 2 x 64 network (gcc 12 -O2, bench/README.md "MLP controller"). */
#define MLP_ROWS 4
/* Rows per thread below which one thread evaluates the batch (a team costs more than a few rows). */
#define MLP_PAR_MIN 64

const char *const wf_mlp_act_names[] = {"identity", "tanh", "relu", NULL};
const char *const wf_mlp_output_names[] = {"acceleration", "speed", NULL};

extern const WfCfModel wf_cf_external, wf_cf_external_speed;

void wf_mlp_init_model(WfMlp *net)
{
    net->model = net->output == WF_MLP_SPEED ? wf_cf_external_speed : wf_cf_external;
    net->model.name = "mlp";
    net->model.doc = net->output == WF_MLP_SPEED
                         ? "feed-forward network (HDF5 file) commanding a set speed, followed by the acc law"
                         : "feed-forward network (HDF5 file) commanding the acceleration";
}

void wf_mlp_destroy(WfMlp **pnet)
{
    if (!pnet || !*pnet) return;
    for (size_t l = 0; l < (*pnet)->n_layers; l++) free((*pnet)->layer[l].w), free((*pnet)->layer[l].b);
    free(*pnet);
    *pnet = NULL;
}

WfMlpOutput wf_mlp_output(const WfMlp *net) { return net->output; }
const char *wf_mlp_path(const WfMlp *net) { return net->path; }
const WfCfModel *wf_mlp_model(const WfMlp *net) { return &net->model; }

/* tanh of a block's MLP_ROWS sums. On x86-64 SLEEF's 2-lane SSE2 tanh (3.5 ulp; every x86-64 has SSE2 and no CPU
 * dispatch is involved, so the bits are the same on every x86-64 machine): in a 2 x 64 network glibc's scalar tanh
 * cost 33 ns a call, 80 % of the evaluation, SLEEF's 10 ns (bench/README.md, "MLP controller"). Elsewhere libm's. */
static void tanh_block(const double *s, double *y)
{
#if defined(__x86_64__)
    _Static_assert(MLP_ROWS % 2 == 0, "pairs of lanes");
    for (int r = 0; r < MLP_ROWS; r += 2) _mm_storeu_pd(y + r, Sleef_tanhd2_u35sse2(_mm_loadu_pd(s + r)));
#else
    for (int r = 0; r < MLP_ROWS; r++) y[r] = tanh(s[r]);
#endif
}

/* A block's MLP_ROWS = 4 rows of one unit as one vector: 4 lanes (AVX2) in the avx2 clone of layer_block, two SSE2
 * pairs otherwise; the same IEEE multiplications and additions either way (no FMA: contraction is off), so the same
 * bits on every x86-64. */
typedef double V4 __attribute__((vector_size(32)));

#define V4_SPLAT(s) ((V4){(s), (s), (s), (s)})

/* The activation of one unit's MLP_ROWS sums into y. */
static void activate(WfMlpAct act, const double *s, double *y)
{
    switch (act) {
    case WF_MLP_TANH:
        tanh_block(s, y);
        break;
    case WF_MLP_RELU: /* written so that NaN passes (the caller reports it), as numpy's maximum does */
        for (int r = 0; r < MLP_ROWS; r++) y[r] = s[r] < 0.0 ? 0.0 : s[r];
        break;
    default:
        for (int r = 0; r < MLP_ROWS; r++) y[r] = s[r];
    }
}

/* One layer on a block: y[j][r] = act(b_j + sum_i w_ji x[i][r]), each sum from the bias adding w_ji x[i][r] for
 * i = 0, 1, ... Eight units at a time (eight independent sums of the block's rows in registers: one unit's sums alone
 * wait on the latency of each addition), then the remaining units one at a time, with the same operations in the same
 * order. */
WF_SIMD_CLONES
static void layer_block(const WfMlpLayer *L, const double *restrict x, double *restrict y)
{
    _Static_assert(MLP_ROWS == 4, "one V4 per unit and block");
    size_t n_in = L->n_in, j = 0;
    double s[MLP_ROWS];
    for (; j + 8 <= L->n_out; j += 8) {
        const double *w = L->w + j * n_in, *bias = L->b + j;
        V4 a0 = V4_SPLAT(bias[0]), a1 = V4_SPLAT(bias[1]), a2 = V4_SPLAT(bias[2]), a3 = V4_SPLAT(bias[3]);
        V4 a4 = V4_SPLAT(bias[4]), a5 = V4_SPLAT(bias[5]), a6 = V4_SPLAT(bias[6]), a7 = V4_SPLAT(bias[7]);
        for (size_t i = 0; i < n_in; i++) {
            V4 xi;
            memcpy(&xi, x + i * MLP_ROWS, sizeof xi);
            a0 += w[i] * xi, a1 += w[n_in + i] * xi, a2 += w[2 * n_in + i] * xi, a3 += w[3 * n_in + i] * xi;
            a4 += w[4 * n_in + i] * xi, a5 += w[5 * n_in + i] * xi, a6 += w[6 * n_in + i] * xi;
            a7 += w[7 * n_in + i] * xi;
        }
        const V4 sums[8] = {a0, a1, a2, a3, a4, a5, a6, a7};
        for (size_t u = 0; u < 8; u++) {
            memcpy(s, &sums[u], sizeof s);
            activate(L->act, s, y + (j + u) * MLP_ROWS);
        }
    }
    for (; j < L->n_out; j++) {
        const double *w = L->w + j * n_in;
        for (int r = 0; r < MLP_ROWS; r++) s[r] = L->b[j];
        for (size_t i = 0; i < n_in; i++)
            for (int r = 0; r < MLP_ROWS; r++) s[r] += w[i] * x[i * MLP_ROWS + r];
        activate(L->act, s, y + j * MLP_ROWS);
    }
}

/* Rows [0, m) of a block (m <= MLP_ROWS); the unused lanes compute on zeros and are dropped. */
static void eval_block(const WfMlp *net, const double *rows, size_t m, double *out)
{
    double buf[2][WF_MLP_MAX_WIDTH * MLP_ROWS]; /* 64 KiB of stack: the loader bounds every layer's width */
    double *x = buf[0], *y = buf[1];
    for (size_t i = 0; i < WF_MLP_INPUTS; i++)
        for (size_t r = 0; r < MLP_ROWS; r++)
            x[i * MLP_ROWS + r] = r < m ? (rows[r * WF_MLP_INPUTS + i] - net->in_mean[i]) / net->in_std[i] : 0.0;
    for (size_t l = 0; l < net->n_layers; l++) {
        layer_block(&net->layer[l], x, y);
        double *t = x;
        x = y, y = t;
    }
    for (size_t r = 0; r < m; r++) {
        double u = x[r] * net->out_scale + net->out_offset;
        out[r] = u < net->out_min ? net->out_min : u > net->out_max ? net->out_max : u;
    }
}

void wf_mlp_eval(const WfMlp *net, const double *rows, size_t n, double *out, int nthreads)
{
    size_t nb = (n + MLP_ROWS - 1) / MLP_ROWS;
    /* Race-free: block k reads its rows and writes only out[k * MLP_ROWS ...]. */
    WF_PAR_FOR(nthreads > 1 && n >= (size_t)nthreads * MLP_PAR_MIN,
               "omp parallel for num_threads(nthreads) schedule(static) default(none) shared(net, rows, n, out, nb)",
               for (size_t k = 0; k < nb; k++) {
                   size_t lo = k * MLP_ROWS, m = n - lo < MLP_ROWS ? n - lo : MLP_ROWS;
                   eval_block(net, rows + lo * WF_MLP_INPUTS, m, out + lo);
               });
}
