/* /summary from the one table of summary fields (src/observe/summary.c): the ring and the corridor writer both call
 * this, each with its boundary, so a field's name, units and meaning are written from one place. */
#include "io/h5summary.h"

#include <string.h>

/* One table's fields as arrays over n entries (classes or groups) of stride bytes from base; all_f64: integer
 * fields too as float64 (the class arrays always were: their type is part of the results' contract). */
static int write_arrays(hid_t g, const WfSummaryField *t, size_t nf, const char *base, size_t stride, size_t n,
                        int all_f64, const WfScenario *sc, WfSummaryBoundary b, WfH5Pass pass, WfError *err)
{
    hsize_t dn = n;
    double a[WF_MAX_CLASSES > WF_MAX_GROUPS ? WF_MAX_CLASSES : WF_MAX_GROUPS];
    int64_t k[WF_MAX_CLASSES > WF_MAX_GROUPS ? WF_MAX_CLASSES : WF_MAX_GROUPS];
    int rc = 0;
    for (size_t i = 0; !rc && i < nf; i++) {
        const WfSummaryField *f = &t[i];
        if (!f->desc[b] || f->sweep_only || !wf_summary_field_on(f, sc)) continue;
        for (size_t c = 0; c < n; c++) a[c] = wf_summary_value(base + c * stride, f);
        if (all_f64 || f->type == WF_SUMMARY_F64) {
            rc = wf_h5_put_f64(g, f->name, pass, 1, &dn, a, f->units, f->desc[b], err);
        } else {
            for (size_t c = 0; c < n; c++) k[c] = (int64_t)a[c];
            rc = wf_h5_put_i64(g, f->name, pass, 1, &dn, k, f->units, f->desc[b], err);
        }
    }
    return rc;
}

int wf_h5_summary_write(hid_t fid, const WfSummary *s, const WfScenario *sc, WfSummaryBoundary b, WfH5Pass pass,
                        WfError *err)
{
    hid_t g = wf_h5_group_pass(fid, "summary", pass, err);
    if (g < 0) return WF_ESYS;
    int rc = 0;
    for (size_t k = 0; !rc && k < wf_summary_n_fields; k++) {
        const WfSummaryField *f = &wf_summary_fields[k];
        if (!f->desc[b] || f->sweep_only || !wf_summary_field_on(f, sc)) continue;
        rc = f->type == WF_SUMMARY_F64
                 ? wf_h5_put_scalar_f64(g, f->name, pass, wf_summary_value(s, f), f->units, f->desc[b], err)
                 : wf_h5_put_scalar_i64(g, f->name, pass, (int64_t)wf_summary_value(s, f), f->units, f->desc[b], err);
    }
    if (!rc)
        rc = write_arrays(g, wf_summary_class_fields, wf_summary_n_class_fields, (const char *)s->cls,
                          sizeof s->cls[0], sc->n_classes, 1, sc, b, pass, err);
    if (!rc)
        rc = write_arrays(g, wf_summary_group_fields, wf_summary_n_group_fields, (const char *)s->grp,
                          sizeof s->grp[0], sc->n_groups, 0, sc, b, pass, err);
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
    for (size_t k = 0; k < wf_summary_n_group_fields; k++) print(wf_summary_group_fields[k].name, ctx);
}
