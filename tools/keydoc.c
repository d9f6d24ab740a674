/* keydoc: prints the generated tables of the docs from the library's own tables (tools/gen-key-docs.sh).
 *   keydoc keys SECTION ring|corridor   a scenario section's key table (include/wavefuel/keys.h)
 *   keydoc params MODEL                 a car-following model's parameter table (WfParamSpec)
 *   keydoc integrators                  the integrator registry
 *   keydoc list                         every table the docs must hold: "keys SECTION BOUNDARY", "params MODEL",
 *                                       "integrators", one a line
 * Exit status 2 for an unknown section or model. */
#include <stdio.h>
#include <string.h>

#include "wavefuel/cf.h"
#include "wavefuel/integrator.h"
#include "wavefuel/keys.h"
#include "wavefuel/param.h"

/* Whether a table has a doc row whose boundary set is exactly `on`, or includes it (exact = 0). */
static int has_rows(const WfKeyTable *t, int on, int exact)
{
    for (size_t i = 0; i < t->n; i++)
        if (!(t->keys[i].flags & WF_KEY_NODOC) && (exact ? t->keys[i].on == on : (t->keys[i].on & on) != 0)) return 1;
    return 0;
}

static int list(void)
{
    /* A section is shown for rings when it has ring keys, and for corridors when it has keys of corridors only
     * (sections whose keys all apply to both are described once, in docs/scenarios.md). */
    for (size_t i = 0; wf_key_tables[i]; i++) {
        if (has_rows(wf_key_tables[i], WF_ON_RING, 0)) printf("keys %s ring\n", wf_key_tables[i]->name);
        if (has_rows(wf_key_tables[i], WF_ON_CORRIDOR, 1)) printf("keys %s corridor\n", wf_key_tables[i]->name);
    }
    for (size_t i = 0; wf_cf_models[i]; i++) printf("params %s\n", wf_cf_models[i]->name);
    printf("integrators\n");
    return 0;
}

static int integrators(void)
{
    printf("| name | kind | method |\n|---|---|---|\n");
    for (size_t i = 0; wf_integrators[i]; i++)
        printf("| `%s` | %s | %s |\n", wf_integrators[i]->name, wf_integ_kind_name(wf_integrators[i]->kind),
               wf_integrators[i]->doc);
    return 0;
}

int main(int argc, char **argv)
{
    if (argc == 2 && !strcmp(argv[1], "list")) return list();
    if (argc == 2 && !strcmp(argv[1], "integrators")) return integrators();
    if (argc == 3 && !strcmp(argv[1], "params")) {
        const WfCfModel *m = NULL;
        WfError err = {0};
        if (wf_cf_model_find(argv[2], &m, &err)) {
            fprintf(stderr, "keydoc: %s\n", err.msg);
            return 2;
        }
        return wf_param_markdown(stdout, m->spec, m->n_spec) ? 1 : 0;
    }
    if (argc == 4 && !strcmp(argv[1], "keys")) {
        const WfKeyTable *t = wf_key_table_find(argv[2]);
        int on = !strcmp(argv[3], "ring") ? WF_ON_RING : !strcmp(argv[3], "corridor") ? WF_ON_CORRIDOR : 0;
        if (!t || !on) {
            fprintf(stderr, "keydoc: unknown section '%s' or boundary '%s'\n", argv[2], argv[3]);
            return 2;
        }
        return wf_keys_markdown(stdout, t, on) ? 1 : 0;
    }
    fprintf(stderr, "usage: keydoc keys SECTION ring|corridor | params MODEL | integrators | list\n");
    return 2;
}
