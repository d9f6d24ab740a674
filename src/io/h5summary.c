/* /summary from the one table of summary fields (src/observe/summary.c): the ring and the corridor writer both call
 * this, each with its boundary, so a field's name, units and meaning are written from one place. */
#include "io/h5summary.h"

#include <string.h>

int wf_h5_summary_write(hid_t fid, const WfSummary *s, size_t n_classes, WfSummaryBoundary b, WfH5Pass pass,
                        WfError *err)
{
    hid_t g = wf_h5_group_pass(fid, "summary", pass, err);
    if (g < 0) return WF_ESYS;
    int rc = 0;
    for (size_t k = 0; !rc && k < wf_summary_n_fields; k++) {
        const WfSummaryField *f = &wf_summary_fields[k];
        if (!f->desc[b] || f->sweep_only) continue;
        rc = f->type == WF_SUMMARY_F64
                 ? wf_h5_put_scalar_f64(g, f->name, pass, wf_summary_value(s, f), f->units, f->desc[b], err)
                 : wf_h5_put_scalar_i64(g, f->name, pass, (int64_t)wf_summary_value(s, f), f->units, f->desc[b], err);
    }
    hsize_t nc = n_classes;
    double a[WF_MAX_CLASSES];
    for (size_t k = 0; !rc && k < wf_summary_n_class_fields; k++) {
        const WfSummaryField *f = &wf_summary_class_fields[k];
        if (!f->desc[b] || f->sweep_only) continue;
        for (size_t c = 0; c < n_classes; c++) a[c] = wf_summary_value(&s->cls[c], f);
        rc = wf_h5_put_f64(g, f->name, pass, 1, &nc, a, f->units, f->desc[b], err);
    }
    H5Gclose(g);
    return rc ? WF_ESYS : 0;
}

void wf_h5_summary_each(void (*print)(const char *name, void *ctx), void *ctx)
{
    /* Each name once: a field may have one entry per boundary (overlaps). */
    for (size_t k = 0; k < wf_summary_n_fields; k++) {
        int seen = 0;
        for (size_t j = 0; j < k; j++) seen |= !strcmp(wf_summary_fields[j].name, wf_summary_fields[k].name);
        if (!seen && !wf_summary_fields[k].sweep_only) print(wf_summary_fields[k].name, ctx);
    }
    for (size_t k = 0; k < wf_summary_n_class_fields; k++)
        if (!wf_summary_class_fields[k].sweep_only) print(wf_summary_class_fields[k].name, ctx);
}
