/* The summary's fields, declared once (include/wavefuel/summary.h): names and units of /summary and of the sweep
 * table, the meaning on each boundary, and how `wavefuel run` prints them. Definitions: docs/metrics.md. */
#include "wavefuel/summary.h"

#include "wavefuel/corridor.h"
#include "wavefuel/safety.h"

#define R WF_SUMMARY_RING
#define C WF_SUMMARY_CORRIDOR
#define F64 WF_SUMMARY_F64
#define I64 WF_SUMMARY_I64
#define NONE WF_SUMMARY_NONE
#define SUM WF_SUMMARY_SUM
#define S(field) offsetof(WfSummary, field)
#define K(field) offsetof(WfClassSummary, field)
/* print[] entries: {label, format, suffix} for the ring, then the corridor. */
#define NOPRINT {{NULL, NULL, NULL}, {NULL, NULL, NULL}}

/* Fleet values, in the order of the printed line (mean speed ... overlaps) and of the sweep table's columns. */
const WfSummaryField wf_summary_fields[] = {
    {"window", "s", {"statistics window (after warm-up)", "statistics window (after warm-up)"}, F64, S(window_s), 0, NOPRINT, 0, 0, 0, 0},
    {"fuel", "g", {"fleet fuel in the window", "fuel burnt on the road in the window"}, F64, S(fuel_g), 0, NOPRINT, 0, 0, 0, 0},
    {"distance", "m", {"fleet distance in the window", "distance travelled on the road in the window"}, F64, S(dist_m),
     0, NOPRINT, 0, 0, 0, 0},
    {"vkt", "km", {"vehicle-kilometres travelled", "vehicle-kilometres travelled in the window"}, F64, S(vkt_km), 0, NOPRINT, 0, 0, 0, 0},
    {"vht", "h", {NULL, "vehicle-hours on the road in the window"}, F64, S(vht_h), 0, NOPRINT, 0, 0, 0, 0},
    {"l_per_100km", "L/100km", {"fleet fuel economy", "fleet fuel economy"}, F64, S(l_per_100km), 0, NOPRINT, 0, 0, 0, 0},
    {"mpg", "mi/gal", {"fleet fuel economy", "fleet fuel economy"}, F64, S(mpg), 0, NOPRINT, 0, 0, 0, 0},
    {"stops_per_vkm", "1/km", {"stops per vehicle-km", "stops per vehicle-km"}, F64, S(stops_per_vkm), 0, NOPRINT, 0, 0, 0, 0},
    {"mean_speed", "m/s", {"fleet mean speed", "distance / vehicle-time in the window"}, F64, S(mean_speed_mps), 0,
     {{"mean speed", "%.3f", "m/s"}, {"mean speed", "%.3f", "m/s"}}, 0, 0, 0, 0},
    {"sd_speed_time_avg", "m/s",
     {"time average of the spatial speed standard deviation",
      "mean over the window's records of the speed s.d. across vehicles"},
     F64, S(sd_speed_time_avg_mps), 0,
     {{"time-avg speed s.d.", "%.3f", "m/s"}, {"time-avg speed s.d.", "%.3f", "m/s"}}, 0, 0, 0, 0},
    {"throughput", "1/h", {"passages of x = 0 per hour", NULL}, F64, S(throughput_vph), 0,
     {{"throughput", "%.1f", "veh/h"}, {NULL, NULL, NULL}}, 0, 0, 0, 0},
    {"inflow", "1/h", {NULL, "entries per hour in the window"}, F64, S(inflow_vph), 0,
     {{NULL, NULL, NULL}, {"inflow", "%.1f", "veh/h"}}, 0, 0, 0, 0},
    {"outflow", "1/h", {NULL, "exits per hour in the window"}, F64, S(outflow_vph), 0,
     {{NULL, NULL, NULL}, {"outflow", "%.1f", "veh/h"}}, 0, 0, 0, 0},
    {"hard_brakes_per_vkm", "1/km", {"hard-braking events per vehicle-km", "hard-braking events per vehicle-km"}, F64,
     S(hard_brakes_per_vkm), 0, {{"hard brakes", "%.3f", "/vkm"}, {"hard brakes", "%.3f", "/vkm"}}, 0, 0, 0, 0},
    {"infeasible_share", "1",
     {"share of vehicle-steps with an infeasible acceleration request",
      "share of vehicle-steps with an infeasible acceleration request"},
     F64, S(infeasible_share), 0, NOPRINT, 0, 0, 0, 0},
    {"time_stopped_share", "1", {"share of time stopped", "share of time stopped"}, F64, S(time_stopped_share), 0, NOPRINT, 0, 0, 0, 0},
    {"trips", "1", {NULL, "completed trips (whole run)"}, I64, S(trips), 0, NOPRINT, 0, 0, 0, 0},
    {"mean_travel_time", "s", {NULL, "mean over completed trips"}, F64, S(mean_travel_time_s), 0, NOPRINT, 0, 0, 0, 0},
    {"mean_trip_fuel", "g", {NULL, "mean over completed trips"}, F64, S(mean_trip_fuel_g), 0, NOPRINT, 0, 0, 0, 0},
    {"mean_queue_delay", "s", {NULL, "mean wait of the entered vehicles"}, F64, S(mean_queue_delay_s), 0, NOPRINT, 0, 0, 0, 0},
    {"arrived", "1", {NULL, "vehicles that reached the entrance"}, I64, S(counts.arrived), 0, NOPRINT, 0, 0, 0, 0},
    {"entered", "1", {NULL, "vehicles inserted at x = 0"}, I64, S(counts.entered), 0, NOPRINT, 0, 0, 0, 0},
    {"exited", "1", {NULL, "vehicles that left at x = L"}, I64, S(counts.exited), 0, NOPRINT, 0, 0, 0, 0},
    {"on_road", "1", {NULL, "vehicles on the road at the end"}, I64, S(on_road), 0, NOPRINT, 0, 0, 0, 0},
    {"queued", "1", {NULL, "vehicles waiting at the entrance at the end"}, I64, S(counts.queued), 0, NOPRINT, 0, 0, 0, 0},
    {"delayed", "1", {NULL, "entries that waited at least one step"}, I64, S(counts.delayed), 0, NOPRINT, 0, 0, 0, 0},
    {"max_queue", "1", {NULL, "longest entrance queue"}, I64, S(counts.max_queue), 0, NOPRINT, 0, 0, 0, 0},
    {"overlaps", "1", {"overlap events repaired", NULL}, I64, S(overlaps), 0,
     {{"overlaps", "%lld", ""}, {NULL, NULL, NULL}}, 0, 0, 0, 0},
    {"overlaps", "1", {NULL, "overlap repairs"}, I64, S(counts.overlaps), 0,
     {{NULL, NULL, NULL}, {"overlaps", "%lld", ""}}, 0, 0, 0, 0},
    {"safety_interventions", "1",
     {"steps whose acceleration a safety filter changed, every group, whole run",
      "steps whose acceleration a safety filter changed, every group, whole run"},
     I64, S(safety_interventions), 0, NOPRINT, 0, 0, 0, WF_SUMMARY_IF_SAFETY},
    {"collisions_repaired", "1",
     {"1: the run repaired overlaps (collisions: a follower put at gap 0 and stopped), its results include them; 0: none",
      "1: the run repaired overlaps (collisions: a follower put at gap 0 and stopped), its results include them; 0: none"},
     I64, S(collisions_repaired), 0, NOPRINT, 0, 0, 0, WF_SUMMARY_IF_SAFETY},
    {"lane_changes", "1", {"lane changes, whole run (docs/lanes.md)", "lane changes, whole run (docs/lanes.md)"}, I64,
     S(lane_changes), 0, {{"lane changes", "%lld", ""}, {"lane changes", "%lld", ""}}, 0, 0, 0, WF_SUMMARY_IF_LANES},
    {"cut_ins", "1",
     {"lane changes into a gap with a follower (cut-ins), whole run",
      "lane changes into a gap with a follower (cut-ins), whole run"},
     I64, S(cut_ins), 0, {{"cut-ins", "%lld", ""}, {"cut-ins", "%lld", ""}}, 0, 0, 0, WF_SUMMARY_IF_LANES},
    {"off_ramp_exits", "1", {NULL, "vehicles that left by the off-ramp (docs/lanes.md)"}, I64, S(counts.off_ramp), 0,
     {{NULL, NULL, NULL}, {"off-ramp exits", "%lld", ""}}, 0, 0, 0, WF_SUMMARY_IF_OFFRAMP},
    {"missed_exits", "1", {NULL, "vehicles bound for the off-ramp that passed it in another lane (and drove on)"}, I64,
     S(counts.missed_exits), 0, {{NULL, NULL, NULL}, {"missed exits", "%lld", ""}}, 0, 0, 0, WF_SUMMARY_IF_OFFRAMP},
};
const size_t wf_summary_n_fields = sizeof wf_summary_fields / sizeof wf_summary_fields[0];

/* Per class, in the order of the printed class table's columns. The ring's class counts are not in /summary (they
 * are /classes/count) but are a column of the printed table and of the sweep table (sweep_only). */
const WfSummaryField wf_summary_class_fields[] = {
    {"class_count", "1", {"vehicles per class", NULL}, WF_SUMMARY_LONG, K(count), SUM,
     {{"count", "%6lld", ""}, {NULL, NULL, NULL}}, 0, 0, 1, 0},
    {"class_entered", "1", {NULL, "vehicles of the class that entered"}, I64, K(entered), SUM,
     {{NULL, NULL, NULL}, {"entered", "%7lld", ""}}, 0, 0, 0, 0},
    {"class_trips", "1", {NULL, "completed trips per class"}, I64, K(trips), S(trips),
     {{NULL, NULL, NULL}, {"trips", "%6lld", ""}}, 0, 0, 0, 0},
    {"class_fuel", "g", {"fuel per class in the window", "fuel per class in the window"}, F64, K(fuel_g), S(fuel_g),
     {{"fuel_g", "%12.2f", ""}, {"fuel_g", "%11.2f", ""}}, 0, 0, 0, 0},
    {"class_distance", "m", {"distance per class in the window", "distance per class in the window"}, F64, K(dist_m),
     S(dist_m), {{"dist_km", "%10.3f", ""}, {"dist_km", "%9.3f", ""}}, 1, 1000, 0, 0},
    {"class_l_per_100km", "L/100km", {"fuel economy per class", "fuel economy per class"}, F64, K(l_per_100km),
     S(l_per_100km), {{"L/100km", "%11.3f", ""}, {"L/100km", "%9.3f", ""}}, 0, 0, 0, 0},
    {"class_mpg", "mi/gal", {"fuel economy per class", "fuel economy per class"}, F64, K(mpg), S(mpg),
     {{"mpg", "%8.2f", ""}, {NULL, NULL, NULL}}, 0, 0, 0, 0},
    {"class_stops_per_vkm", "1/km", {"stops per vehicle-km per class", "stops per vehicle-km per class"}, F64,
     K(stops_per_vkm), S(stops_per_vkm), {{"stops/vkm", "%10.3f", ""}, {"stops/vkm", "%9.3f", ""}}, 0, 0, 0, 0},
    {"class_infeasible_share", "1",
     {"infeasible acceleration share per class", "infeasible acceleration share per class"}, F64,
     K(infeasible_share), S(infeasible_share), {{"infeasible", "%10.2f%%", ""}, {NULL, NULL, NULL}}, 100, 1, 0, 0},
    {"class_trip_fuel_mean", "g", {NULL, "mean fuel of the class's completed trips"}, F64, K(trip_fuel_mean_g),
     S(mean_trip_fuel_g), {{NULL, NULL, NULL}, {"trip_g", "%9.2f", ""}}, 0, 0, 0, 0},
    {"class_trip_time_mean", "s", {NULL, "mean travel time of the class's completed trips"}, F64, K(trip_time_mean_s),
     S(mean_travel_time_s), {{NULL, NULL, NULL}, {"trip_s", "%9.1f", ""}}, 0, 0, 0, 0},
    {"class_g_per_km_up", "g/km", {NULL, "fuel per vehicle-km on climbing cells (mean grade > 1e-4 rad)"}, F64,
     K(g_per_km_up), NONE, {{NULL, NULL, NULL}, {"g/km_up", "%9.2f", ""}}, 0, 0, 0, 0},
    {"class_g_per_km_down", "g/km", {NULL, "fuel per vehicle-km on descending cells (< -1e-4 rad)"}, F64,
     K(g_per_km_down), NONE, {{NULL, NULL, NULL}, {"g/km_dn", "%9.2f", ""}}, 0, 0, 0, 0},
    {"class_g_per_km_flat", "g/km", {NULL, "fuel per vehicle-km on the other cells"}, F64, K(g_per_km_flat), NONE,
     {{NULL, NULL, NULL}, {"g/km_flat", "%9.2f", ""}}, 0, 0, 0, 0},
};
const size_t wf_summary_n_class_fields = sizeof wf_summary_class_fields / sizeof wf_summary_class_fields[0];

#define G(field) offsetof(WfGroupSummary, field)
/* Per driver group, in the order of the printed safety line; whole run (a safety event count, like overlaps). */
const WfSummaryField wf_summary_group_fields[] = {
    {"group_safety_steps", "1",
     {"vehicle-steps per driver group under its safety filter (0: no filter), whole run",
      "vehicle-steps per driver group under its safety filter (0: no filter), whole run"},
     I64, G(safety_steps), NONE, {{"vehicle-steps", "%lld", ""}, {"vehicle-steps", "%lld", ""}}, 0, 0, 0,
     WF_SUMMARY_IF_SAFETY},
    {"group_safety_interventions", "1",
     {"steps whose acceleration the group's safety filter changed, whole run",
      "steps whose acceleration the group's safety filter changed, whole run"},
     I64, G(safety_interventions), NONE, {{"interventions", "%lld", ""}, {"interventions", "%lld", ""}}, 0, 0, 0,
     WF_SUMMARY_IF_SAFETY},
    {"group_safety_share", "1",
     {"interventions / vehicle-steps of the group (0 when none)", "interventions / vehicle-steps of the group (0 when none)"},
     F64, G(safety_share), NONE, {{"share", "%.3f", "%"}, {"share", "%.3f", "%"}}, 100, 1, 0, WF_SUMMARY_IF_SAFETY},
};
const size_t wf_summary_n_group_fields = sizeof wf_summary_group_fields / sizeof wf_summary_group_fields[0];

int wf_scenario_has_safety(const WfScenario *sc)
{
    for (size_t g = 0; g < sc->n_groups; g++)
        if (sc->groups[g].safety) return 1;
    return 0;
}

int wf_summary_field_on(const WfSummaryField *f, const WfScenario *sc)
{
    if (f->when == WF_SUMMARY_IF_LANES) return wf_scenario_lanes(sc) > 1;
    if (f->when == WF_SUMMARY_IF_OFFRAMP) return sc->corridor && sc->corridor->has_offramp;
    return f->when == WF_SUMMARY_ALWAYS || wf_scenario_has_safety(sc);
}

void wf_summary_safety_totals(WfSummary *s)
{
    s->safety_interventions = 0;
    for (size_t g = 0; g < WF_MAX_GROUPS; g++) {
        WfGroupSummary *gs = &s->grp[g];
        gs->safety_share = gs->safety_steps > 0 ? (double)gs->safety_interventions / (double)gs->safety_steps : 0.0;
        s->safety_interventions += gs->safety_interventions;
    }
    s->collisions_repaired = s->overlaps + s->counts.overlaps > 0;
}

double wf_summary_value(const void *base, const WfSummaryField *f)
{
    const char *p = (const char *)base + f->offset;
    switch (f->type) {
    case WF_SUMMARY_I64: return (double)*(const int64_t *)p;
    case WF_SUMMARY_LONG: return (double)*(const long *)p;
    default: return *(const double *)p;
    }
}

/* The printed value: the field's value x print_mul / print_div (a percentage, km from m); integer fields as
 * integers. Returns the characters written to buf. */
static int print_value(char *buf, size_t len, const WfSummaryField *f, const char *format, double v)
{
    if (f->type != WF_SUMMARY_F64) return snprintf(buf, len, format, (long long)v);
    if (f->print_mul) v = f->print_mul * v;
    if (f->print_div) v = v / f->print_div;
    return snprintf(buf, len, format, v);
}

/* Width of a column: that of its values (the header is right-aligned above them). */
static int column_width(const WfSummaryField *f, const WfSummaryPrint *p)
{
    char buf[64];
    return print_value(buf, sizeof buf, f, p->format, 0.0);
}

/* One row of the class table: name, then each printed column (blank where the fleet row has no value); trailing
 * blanks are dropped. */
static void print_row(FILE *out, const char *name, const void *base, int fleet, WfSummaryBoundary b)
{
    char line[1024];
    int used = snprintf(line, sizeof line, "%-16s", name), end = used;
    for (size_t k = 0; k < wf_summary_n_class_fields && used < (int)sizeof line - 64; k++) {
        const WfSummaryField *f = &wf_summary_class_fields[k];
        const WfSummaryPrint *p = &f->print[b];
        if (!p->label) continue;
        if (fleet && f->fleet_offset == NONE) {
            used += snprintf(line + used, sizeof line - (size_t)used, " %*s", column_width(f, p), "");
            continue;
        }
        double v = 0.0;
        if (!fleet) {
            v = wf_summary_value(base, f);
        } else if (f->fleet_offset == SUM) {
            const WfSummary *s = base;
            for (size_t c = 0; c < WF_MAX_CLASSES; c++) v += wf_summary_value(&s->cls[c], f);
        } else {
            WfSummaryField ff = *f;
            ff.offset = f->fleet_offset;
            v = wf_summary_value(base, &ff);
        }
        line[used++] = ' ';
        used += print_value(line + used, sizeof line - (size_t)used, f, p->format, v);
        end = used;
    }
    line[end] = '\0';
    fprintf(out, "%s\n", line);
}

/* The printed fields of base that the scenario has, "LABEL VALUE[ SUFFIX]" joined by " | " after sep, one line. */
static void print_line(FILE *out, const WfSummaryField *fields, size_t n, WfSummaryBoundary b, const void *base,
                       const WfScenario *sc, const char *sep)
{
    for (size_t k = 0; k < n; k++) {
        const WfSummaryField *f = &fields[k];
        const WfSummaryPrint *p = &f->print[b];
        if (!p->label || !wf_summary_field_on(f, sc)) continue;
        char val[64];
        print_value(val, sizeof val, f, p->format, wf_summary_value(base, f));
        fprintf(out, "%s%s %s%s%s", sep, p->label, val, p->suffix[0] ? " " : "", p->suffix);
        sep = " | ";
    }
    fprintf(out, "\n");
}

void wf_summary_print(FILE *out, const WfSummary *s, WfSummaryBoundary b, const char *const *names, size_t n_classes,
                      const WfScenario *sc)
{
    fprintf(out, "%-16s", "class");
    for (size_t k = 0; k < wf_summary_n_class_fields; k++) {
        const WfSummaryPrint *p = &wf_summary_class_fields[k].print[b];
        if (p->label) fprintf(out, " %*s", column_width(&wf_summary_class_fields[k], p), p->label);
    }
    fprintf(out, "\n");
    for (size_t c = 0; c < n_classes; c++) print_row(out, names[c], &s->cls[c], 0, b);
    print_row(out, "fleet", s, 1, b);
    fprintf(out, "\n");
    print_line(out, wf_summary_fields, wf_summary_n_fields, b, s, sc, "");
}

void wf_summary_print_safety(FILE *out, const WfSummary *s, WfSummaryBoundary b, const WfScenario *sc)
{
    for (size_t g = 0; g < sc->n_groups; g++) {
        if (!sc->groups[g].safety) continue;
        fprintf(out, "safety filter %s, group %s:", sc->groups[g].safety->name, sc->groups[g].name);
        print_line(out, wf_summary_group_fields, wf_summary_n_group_fields, b, &s->grp[g], sc, " ");
    }
    wf_summary_warn_repairs(out, (long long)(s->overlaps + s->counts.overlaps));
}

void wf_summary_warn_repairs(FILE *out, long long repaired)
{
    if (repaired > 0)
        fprintf(out, "warning: %lld overlap repair%s: these results include repaired collisions (a follower put at gap 0 "
                "and stopped; docs/metrics.md)\n", repaired, repaired == 1 ? "" : "s");
}
