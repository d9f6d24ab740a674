/* Proportional-integral controller with saturation (Stern et al. 2018, Transp. Res. C 89, 205, Sec. 3.2):
 *   U        = running average of the AV's own speed over the last window_s (38 s)
 *   v_target = U + v_catch clip((gap - g_l)/(g_u - g_l), 0, 1)
 *   dx_s     = max(T_s (v_lead - v), dx_s_min)     (the paper's max(2 dv, 4 m))
 *   alpha    = clip((gap - dx_s)/gamma, 0, 1),  beta = 1 - alpha/2
 *   v_cmd   <- beta (alpha v_target + (1 - alpha) v_lead) + (1 - beta) v_cmd     (once per step)
 *   a        = k (v_cmd - v)
 * Gaps in m, speeds in m/s, k in 1/s. Memory per vehicle: the previous command and the speed history. */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "wavefuel/cf.h"
#include "util/numfmt.h"

/* The speed history is sampled on a fixed clock of PI_SAMPLE_S, independent of the time step, so the state
 * block has one size for every scenario: at t_j = j PI_SAMPLE_S the speed at the start of the step containing
 * t_j is stored (sample and hold; with dt = PI_SAMPLE_S that is every step's speed). The average U is the mean
 * of the newest n - 1 stored samples and the current speed, n = round(window_s / PI_SAMPLE_S): with
 * dt = 0.1 s that is exactly the mean of the last n step speeds, the current one included, as in Flow's
 * PISaturation. Until n - 1 samples exist, the mean runs over those there are. */
#define PI_SAMPLE_S   0.1
#define PI_WINDOW_MAX 120.0
#define PI_CAPACITY   1200 /* PI_WINDOW_MAX / PI_SAMPLE_S */

typedef struct PiParams {
    double window_s;    /* averaging window of the own speed */
    double v_catch_mps; /* catch-up speed added at large gaps */
    double g_l_m;       /* gap where the catch-up term starts */
    double g_u_m;       /* gap where it saturates */
    double gamma_m;     /* width of the blend between the target and the leader's speed */
    double dx_s_min_m;  /* smallest safe gap */
    double dx_s_T_s;    /* safe gap per m/s of (v_lead - v) */
    double k_per_s;     /* speed-tracking gain */
} PiParams;

typedef struct PiState {
    double   v_cmd_mps;  /* command of the last completed step */
    double   hist_sum;   /* sum of the newest min(n_stored, n - 1) samples, re-summed at every update */
    double   hist_count; /* how many samples hist_sum holds */
    uint64_t steps;      /* completed steps: the sampling clock is steps * dt (no accumulated rounding) */
    uint32_t n_stored;   /* valid samples, <= PI_CAPACITY */
    uint32_t head;       /* slot of the next sample */
    double   hist_mps[PI_CAPACITY];
} PiState;

static const WfParamSpec pi_spec[] = {
    {"window_s", offsetof(PiParams, window_s), 38.0, PI_SAMPLE_S, PI_WINDOW_MAX, "s", 0,
     "averaging window of the AV's own speed (sampled every 0.1 s)"},
    {"v_catch_mps", offsetof(PiParams, v_catch_mps), 1.0, 0.0, 10.0, "m/s", 0,
     "catch-up speed added to the average at large gaps"},
    {"g_l_m", offsetof(PiParams, g_l_m), 7.0, 0.0, 200.0, "m", 0, "gap where the catch-up term starts"},
    {"g_u_m", offsetof(PiParams, g_u_m), 30.0, 0.1, 500.0, "m", 0, "gap where the catch-up term saturates"},
    {"gamma_m", offsetof(PiParams, gamma_m), 2.0, 0.01, 50.0, "m", 0,
     "blend width between the target speed and the leader's speed"},
    {"dx_s_min_m", offsetof(PiParams, dx_s_min_m), 4.0, 0.0, 50.0, "m", 0, "smallest safe gap"},
    {"dx_s_T_s", offsetof(PiParams, dx_s_T_s), 2.0, 0.0, 10.0, "s", 0,
     "safe gap per m/s of speed difference (v_lead - v)"},
    /* As FollowerStopper's: 1 s time constant; k = 1/dt gives Flow's one-step tracking. */
    {"k_per_s", offsetof(PiParams, k_per_s), 1.0, 0.01, 100.0, "1/s", 0, "speed-tracking gain: a = k (v_cmd - v)"},
};

static double clip01(double x) { return x < 0.0 ? 0.0 : (x > 1.0 ? 1.0 : x); }

/* The command of this step from the stored memory and this step's inputs. check() ensures g_u > g_l;
 * gamma >= 0.01 m by its range. */
static double pi_command(const PiParams *p, const PiState *s, double gap_m, double v_mps, double v_lead_mps)
{
    double U = (s->hist_sum + v_mps) / (s->hist_count + 1.0);
    double v_target = U + p->v_catch_mps * clip01((gap_m - p->g_l_m) / (p->g_u_m - p->g_l_m));
    double dx_s = fmax(p->dx_s_T_s * (v_lead_mps - v_mps), p->dx_s_min_m);
    double alpha = clip01((gap_m - dx_s) / p->gamma_m);
    double beta = 1.0 - 0.5 * alpha;
    return beta * (alpha * v_target + (1.0 - alpha) * v_lead_mps) + (1.0 - beta) * s->v_cmd_mps;
}

static double pi_accel(const void *params, const void *state, double gap_m, double v_mps, double v_lead_mps)
{
    const PiParams *p = params;
    if (!state) {
        /* Called without memory only by the uniform-flow solvers (initial conditions). A settled PI controller
         * has a whole interval of equilibrium gaps (it follows the leader below g_l and closes larger gaps), so
         * it reports the sign of (gap - g_l) through a stand-in that tracks v_lead + v_catch clip((gap -
         * g_l)/(g_u - g_l), -1, 1): initial conditions put the AV at g_l, the largest gap at which it neither
         * closes in nor falls back. */
        double r = (gap_m - p->g_l_m) / (p->g_u_m - p->g_l_m);
        r = r < -1.0 ? -1.0 : (r > 1.0 ? 1.0 : r);
        return p->k_per_s * (v_lead_mps + p->v_catch_mps * r - v_mps);
    }
    return p->k_per_s * (pi_command(p, state, gap_m, v_mps, v_lead_mps) - v_mps);
}

static void pi_init_state(const void *params, void *state, double gap_m, double v_mps, double v_lead_mps)
{
    (void)params, (void)gap_m, (void)v_lead_mps;
    PiState *s = state;
    memset(s, 0, sizeof *s);
    /* Starting from the current speed: the filter then has no transient from an arbitrary 0 command. */
    s->v_cmd_mps = v_mps;
}

/* Samples due on the clock j PI_SAMPLE_S up to time t: those with j PI_SAMPLE_S < t, i.e. ceil(t / h); the
 * 1e-9 guards against t / h landing a rounding error above an integer (0.3 / 0.1 = 3.0000000000000004). */
static uint64_t samples_before(uint64_t steps, double dt_s)
{
    double q = (double)steps * dt_s / PI_SAMPLE_S;
    return (uint64_t)ceil(q - 1e-9);
}

static void pi_update_state(const void *params, void *state, double gap_m, double v_mps, double v_lead_mps,
                            double dt_s)
{
    const PiParams *p = params;
    PiState *s = state;
    /* The command first: it must be the one accel() used in this step, computed from the old memory. */
    s->v_cmd_mps = pi_command(p, s, gap_m, v_mps, v_lead_mps);
    uint64_t due = samples_before(s->steps + 1, dt_s) - samples_before(s->steps, dt_s);
    s->steps++;
    for (uint64_t j = 0; j < due; j++) {
        s->hist_mps[s->head] = v_mps;
        s->head = (s->head + 1) % PI_CAPACITY;
        if (s->n_stored < PI_CAPACITY) s->n_stored++;
    }
    /* Re-summed (newest first) rather than updated by add/subtract, so no rounding accumulates over a long
     * run; at most PI_CAPACITY additions per AV and step. */
    long want = lround(p->window_s / PI_SAMPLE_S) - 1; /* n - 1 samples beside the current speed */
    uint32_t take = (long)s->n_stored < want ? s->n_stored : (uint32_t)want;
    double sum = 0.0;
    for (uint32_t j = 0; j < take; j++) sum += s->hist_mps[(s->head + PI_CAPACITY - 1 - j) % PI_CAPACITY];
    s->hist_sum = sum;
    s->hist_count = (double)take;
}

static int pi_check(const void *params, WfError *err)
{
    const PiParams *p = params;
    if (!(p->g_u_m > p->g_l_m))
        return wf_err(err, WF_EINPUT, "pi_saturation: need g_u_m > g_l_m (got g_l_m = %s, g_u_m = %s)",
                      WF_NUM(p->g_l_m), WF_NUM(p->g_u_m));
    return 0;
}

const WfCfModel wf_cf_pi_saturation = {
    .name = "pi_saturation",
    .doc = "PI controller with saturation (Stern et al. 2018)",
    .param_size = sizeof(PiParams),
    .spec = pi_spec,
    .n_spec = sizeof pi_spec / sizeof pi_spec[0],
    .check = pi_check,
    .accel = pi_accel,
    .state_size = sizeof(PiState),
    .init_state = pi_init_state,
    .update_state = pi_update_state,
};
