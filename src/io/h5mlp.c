/* The network file of a `model: mlp` driver group (docs/controllers.md, "mlp: learned controllers"): read with
 * every shape, value and name checked, so that evaluation (src/models/cf/mlp.c) can trust it. Every refusal names
 * the file and the dataset. */
#include <errno.h>
#include <hdf5.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "io/h5util.h"
#include "models/cf/mlp.h"
#include "util/numfmt.h"
#include "util/registry.h"

#define MLP_FORMAT "wavefuel-mlp 1"

/* A float dataset `name` of rank 2 (dims[0] x dims[1]), 1 (dims[0]) or a scalar (rank 0, or shape [1]), read as
 * doubles into a malloc'd *out (NULL for the caller to allocate nothing when out is NULL: shape only). want_rank
 * 0 accepts a scalar. Every value must be finite. */
static int read_f64(hid_t f, const char *file, const char *name, int want_rank, hsize_t dims[2], double **out,
                    WfError *err)
{
    *out = NULL;
    if (H5Lexists(f, name, H5P_DEFAULT) <= 0) return wf_err(err, WF_EINPUT, "%s: no dataset '%s'", file, name);
    int rank = -1, rc = 0;
    hsize_t dm[H5S_MAX_RANK] = {0};
    H5T_class_t cls = H5T_NO_CLASS;
    if (H5LTget_dataset_ndims(f, name, &rank) < 0 || rank < 0 || rank > H5S_MAX_RANK ||
        H5LTget_dataset_info(f, name, dm, &cls, NULL) < 0)
        rank = -1, cls = H5T_NO_CLASS;
    int scalar = rank == 0 || (rank == 1 && dm[0] == 1);
    if (cls != H5T_FLOAT)
        rc = wf_err(err, WF_EINPUT, "%s: dataset '%s' is not floating-point", file, name);
    else if (want_rank == 0 ? !scalar : rank != want_rank) {
        char shape[96] = "";
        for (int k = 0, used = 0; k < rank && k < 4 && used < 80; k++)
            used += snprintf(shape + used, sizeof shape - (size_t)used, "%s%llu", k ? ", " : "",
                             (unsigned long long)dm[k]);
        rc = wf_err(err, WF_EINPUT, "%s: dataset '%s' has shape [%s], expected %s", file, name, shape,
                    want_rank == 0 ? "a scalar" : want_rank == 1 ? "a vector" : "a matrix [outputs, inputs]");
    }
    size_t n = rc ? 0 : want_rank == 0 ? 1 : want_rank == 1 ? (size_t)dm[0] : (size_t)(dm[0] * dm[1]);
    if (!rc && n > (size_t)WF_MLP_MAX_WIDTH * WF_MLP_MAX_WIDTH)
        rc = wf_err(err, WF_EINPUT, "%s: dataset '%s' has %zu values, more than a layer of %d x %d units", file, name,
                    n, WF_MLP_MAX_WIDTH, WF_MLP_MAX_WIDTH);
    double *v = rc ? NULL : malloc((n ? n : 1) * sizeof *v);
    if (!rc && !v) rc = wf_err(err, WF_ESYS, "out of memory for %s: %s", file, name);
    if (!rc && n && H5LTread_dataset_double(f, name, v) < 0)
        rc = wf_err(err, WF_ESYS, "%s: HDF5: read dataset '%s' failed", file, name);
    for (size_t k = 0; !rc && k < n; k++)
        if (!isfinite(v[k])) {
            if (want_rank == 2)
                rc = wf_err(err, WF_EINPUT, "%s: dataset '%s': element [%zu, %zu] is %s (weights must be finite)",
                            file, name, k / (size_t)dm[1], k % (size_t)dm[1], WF_NUM(v[k]));
            else
                rc = wf_err(err, WF_EINPUT, "%s: dataset '%s': element %zu is %s (values must be finite)", file, name,
                            k, WF_NUM(v[k]));
        }
    if (!rc) {
        dims[0] = want_rank >= 1 ? dm[0] : 1, dims[1] = want_rank == 2 ? dm[1] : 1;
        *out = v;
    } else {
        free(v);
    }
    return rc;
}

/* A scalar float dataset into *v; optional ones (required = 0) leave *v when absent. */
static int read_scalar(hid_t f, const char *file, const char *name, int required, double *v, WfError *err)
{
    if (!required && H5Lexists(f, name, H5P_DEFAULT) <= 0) return 0;
    hsize_t dims[2];
    double *x = NULL;
    if (read_f64(f, file, name, 0, dims, &x, err)) return err->code;
    *v = x[0];
    free(x);
    return 0;
}

/* A scalar string dataset that must be one of names[] (NULL-terminated); its index into *out. */
static int read_choice(hid_t f, const char *file, const char *name, const char *const *names, int *out, WfError *err)
{
    char *s = NULL;
    if (H5Lexists(f, name, H5P_DEFAULT) <= 0) return wf_err(err, WF_EINPUT, "%s: no dataset '%s'", file, name);
    if (wf_h5_read_scalar_str(f, file, name, &s, err)) return err->code;
    int k = 0;
    while (names[k] && strcmp(names[k], s) != 0) k++;
    int rc = 0;
    if (!names[k]) {
        char known[1024];
        wf_registry_names((const void *const *)names, WF_REG_STRINGS, known, sizeof known);
        rc = wf_err(err, WF_EINPUT, "%s: dataset '%s' is '%.64s': expected one of %s", file, name, s, known);
    }
    *out = k;
    free(s);
    return rc;
}

/* Input normalisation: mean and std of each of the WF_MLP_INPUTS observation columns. */
static int read_inputs(hid_t f, WfMlp *net, WfError *err)
{
    static const char *const names[2] = {"input/mean", "input/std"};
    double *dst[2] = {net->in_mean, net->in_std};
    for (int q = 0; q < 2; q++) {
        hsize_t dims[2];
        double *x = NULL;
        if (read_f64(f, net->path, names[q], 1, dims, &x, err)) return err->code;
        int rc = 0;
        if (dims[0] != WF_MLP_INPUTS)
            rc = wf_err(err, WF_EINPUT, "%s: dataset '%s' has %llu values: the observation row has %d (own speed, "
                        "leader speed, gap)", net->path, names[q], (unsigned long long)dims[0], WF_MLP_INPUTS);
        for (int i = 0; !rc && i < WF_MLP_INPUTS; i++) {
            dst[q][i] = x[i];
            if (q == 1 && !(x[i] > 0.0))
                rc = wf_err(err, WF_EINPUT, "%s: dataset 'input/std': element %d is %s (must be > 0)", net->path, i,
                            WF_NUM(x[i]));
        }
        free(x);
        if (rc) return rc;
    }
    return 0;
}

/* Layer l: layers/l/weight [n_out, n_in], layers/l/bias [n_out], layers/l/activation; n_in is the previous
 * layer's n_out (the first: the observation row). */
static int read_layer(hid_t f, WfMlp *net, size_t l, WfError *err)
{
    WfMlpLayer *L = &net->layer[l];
    char wn[64], bn[64], an[64];
    snprintf(wn, sizeof wn, "layers/%zu/weight", l);
    snprintf(bn, sizeof bn, "layers/%zu/bias", l);
    snprintf(an, sizeof an, "layers/%zu/activation", l);
    hsize_t wd[2], bd[2];
    if (read_f64(f, net->path, wn, 2, wd, &L->w, err)) return err->code;
    size_t want_in = l ? net->layer[l - 1].n_out : WF_MLP_INPUTS;
    L->n_out = (size_t)wd[0], L->n_in = (size_t)wd[1];
    if (L->n_in != want_in)
        return wf_err(err, WF_EINPUT, "%s: dataset '%s' has shape [%zu, %zu]: this layer takes %zu inputs (%s)",
                      net->path, wn, L->n_out, L->n_in, want_in,
                      l ? "the previous layer's outputs" : "the observation row: own speed, leader speed, gap");
    if (L->n_out < 1 || L->n_out > WF_MLP_MAX_WIDTH)
        return wf_err(err, WF_EINPUT, "%s: dataset '%s' has %zu outputs: a layer has 1 to %d", net->path, wn, L->n_out,
                      WF_MLP_MAX_WIDTH);
    if (read_f64(f, net->path, bn, 1, bd, &L->b, err)) return err->code;
    if ((size_t)bd[0] != L->n_out)
        return wf_err(err, WF_EINPUT, "%s: dataset '%s' has %llu values, '%s' has %zu rows", net->path, bn,
                      (unsigned long long)bd[0], wn, L->n_out);
    int act = 0;
    if (read_choice(f, net->path, an, wf_mlp_act_names, &act, err)) return err->code;
    L->act = (WfMlpAct)act;
    return 0;
}

static int read_layers(hid_t f, WfMlp *net, WfError *err)
{
    H5G_info_t info;
    hid_t g = H5Lexists(f, "layers", H5P_DEFAULT) > 0 ? H5Gopen2(f, "layers", H5P_DEFAULT) : H5I_INVALID_HID;
    if (g < 0) return wf_err(err, WF_EINPUT, "%s: no group 'layers'", net->path);
    herr_t st = H5Gget_info(g, &info);
    H5Gclose(g);
    if (st < 0) return wf_err(err, WF_ESYS, "%s: HDF5: reading group 'layers' failed", net->path);
    if (info.nlinks < 1 || info.nlinks > WF_MLP_MAX_LAYERS)
        return wf_err(err, WF_EINPUT, "%s: group 'layers' has %llu members: a network has 1 to %d layers, "
                      "layers/0 ... layers/N-1", net->path, (unsigned long long)info.nlinks, WF_MLP_MAX_LAYERS);
    for (size_t l = 0; l < (size_t)info.nlinks; l++) {
        char name[32];
        snprintf(name, sizeof name, "layers/%zu", l);
        if (H5Lexists(f, name, H5P_DEFAULT) <= 0)
            return wf_err(err, WF_EINPUT, "%s: no group '%s' (the %llu members of 'layers' must be 0 ... %llu)",
                          net->path, name, (unsigned long long)info.nlinks, (unsigned long long)info.nlinks - 1);
        net->n_layers = l + 1; /* owns what read_layer allocated, even on failure */
        if (read_layer(f, net, l, err)) return err->code;
    }
    size_t last = net->layer[net->n_layers - 1].n_out;
    if (last != 1)
        return wf_err(err, WF_EINPUT, "%s: dataset 'layers/%zu/weight' has %zu outputs: the last layer gives one "
                      "command", net->path, net->n_layers - 1, last);
    return 0;
}

static int read_output(hid_t f, WfMlp *net, WfError *err)
{
    int kind = 0;
    net->out_min = -INFINITY, net->out_max = INFINITY;
    if (read_choice(f, net->path, "output/kind", wf_mlp_output_names, &kind, err) ||
        read_scalar(f, net->path, "output/scale", 1, &net->out_scale, err) ||
        read_scalar(f, net->path, "output/offset", 1, &net->out_offset, err) ||
        read_scalar(f, net->path, "output/min", 0, &net->out_min, err) ||
        read_scalar(f, net->path, "output/max", 0, &net->out_max, err))
        return err->code;
    net->output = (WfMlpOutput)kind;
    if (!(net->out_min < net->out_max))
        return wf_err(err, WF_EINPUT, "%s: datasets 'output/min' and 'output/max': %s is not below %s", net->path,
                      WF_NUM(net->out_min), WF_NUM(net->out_max));
    return 0;
}

static int read_network(hid_t f, WfMlp *net, WfError *err)
{
    int fmt = 0;
    static const char *const formats[] = {MLP_FORMAT, NULL};
    if (read_choice(f, net->path, "format", formats, &fmt, err)) return err->code;
    return read_inputs(f, net, err) || read_layers(f, net, err) || read_output(f, net, err) ? err->code : 0;
}

int wf_mlp_load(const char *path, WfMlp **out, WfError *err)
{
    *out = NULL;
    wf_h5_library_init();
    FILE *probe = fopen(path, "rb");
    if (!probe) return wf_err(err, WF_EINPUT, "%s: cannot open the network file: %s", path, strerror(errno));
    fclose(probe);
    if (H5Fis_hdf5(path) <= 0) return wf_err(err, WF_EINPUT, "%s: not an HDF5 file (a network file is HDF5)", path);
    WfMlp *net = calloc(1, sizeof *net);
    if (!net) return wf_err(err, WF_ESYS, "out of memory");
    int n = snprintf(net->path, sizeof net->path, "%s", path), rc = 0;
    hid_t f = H5I_INVALID_HID;
    if (n < 0 || (size_t)n >= sizeof net->path)
        rc = wf_err(err, WF_EINPUT, "network path too long: %.80s...", path);
    else if ((f = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT)) < 0)
        rc = wf_err(err, WF_EINPUT, "%s: cannot open as HDF5", path);
    else
        rc = read_network(f, net, err);
    if (f >= 0) H5Fclose(f);
    if (rc) {
        wf_mlp_destroy(&net);
        return rc;
    }
    wf_mlp_init_model(net);
    *out = net;
    return 0;
}
