/* The result writer's table-driven parts: any observer's columns written from its table. */
#include "io/h5result.h"

int wf_h5_put_columns(hid_t g, const WfObsColumn *cols, const WfObsData *data, size_t n, WfH5Pass pass,
                      WfError *err)
{
    int rc = 0;
    for (size_t k = 0; !rc && k < n; k++) {
        const WfColumn *c = &cols[k].col;
        const WfObsData *d = &data[k];
        hsize_t dims[2] = {d->dims[0], d->dims[1]};
        if (cols[k].at_start && pass != WF_H5_ALLOCATE) continue;
        if (cols[k].at_start)
            rc = cols[k].type == WF_COL_I64
                     ? wf_h5_write_i64(g, c->name, d->rank, dims, d->data, c->units, c->desc, err)
                     : wf_h5_write_f64(g, c->name, d->rank, dims, d->data, c->units, c->desc, err);
        else
            rc = cols[k].type == WF_COL_I64
                     ? wf_h5_put_i64(g, c->name, pass, d->rank, dims, d->data, c->units, c->desc, err)
                     : wf_h5_put_f64(g, c->name, pass, d->rank, dims, d->data, c->units, c->desc, err);
    }
    return rc;
}
