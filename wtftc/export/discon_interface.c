/* The Bladed-style DISCON entry point of a wtftc controller library (wtftc export discon).
 *
 * ServoDyn calls DISCON(avrSWAP, aviFAIL, accINFILE, avcOUTNAME, avcMSG) every DLL_DT
 * (OpenFAST modules/servodyn/src/BladedInterface.f90; ROSCO's ReadSetParameters.f90 reads
 * the same records). Records are 1-based in the docs, C index = record - 1:
 *   read:  #1 iStatus (0 first, 1 running, -1 final; -8/-9 checkpoint/restart refused),
 *          #2 time, #3 interval, #4/#33/#34 blade pitch [rad], #20 generator speed
 *          [rad/s, HSS], #21 rotor speed [rad/s], #28 Ptch_Cntrl (must be 1: individual
 *          pitch), #50 accINFILE length, #63 first logging record;
 *   write: #42-#44 pitch demands [rad] (within pitch_min..pitch_max, and rate-limited
 *          to pitch_rate_max when demand_rate_limit = 1: limit_demands), #45 = #42, #47
 *          generator torque demand [N m, HSS], #35 = 1, #36 = 0, #55 = #56 = 0, #65 =
 *          logged channels.
 * Every error sets aviFAIL < 0 with a NUL-terminated message in avcMSG and returns; the
 * host is never crashed and no record is written from a half-read state. avcMSG gets at
 * most #49 bytes, its NUL included (ServoDyn: its message length + 1); nothing when #49
 * is below 1. The first call checks every value of the input file against its valid range
 * and wtftc's cross-checks (wtftc_discon_checks.h); no call returns aviFAIL = 0 with a
 * demand that is not a finite float.
 *
 * The generated functions (wtftc_step, wtftc_init), the parameter names and the checks
 * come from wtftc_discon_gen.c, wtftc_discon_meta.h and wtftc_discon_checks.h, written by
 * the export.
 */
#define _POSIX_C_SOURCE 200809L /* stat() and S_ISREG under -std=c99 */
#include <ctype.h>
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "wtftc_discon_meta.h"
#include "wtftc_discon_checks.h"

typedef long long casadi_int;
typedef double casadi_real;
int wtftc_schedule_points(const char *path, const double *p, double *betas, double *grads,
                          int n_max, char *err, size_t n_err);
int wtftc_step(const casadi_real **arg, casadi_real **res, casadi_int *iw, casadi_real *w,
               int mem);
int wtftc_init(const casadi_real **arg, casadi_real **res, casadi_int *iw, casadi_real *w,
               int mem);
int wtftc_step_work(casadi_int *sz_arg, casadi_int *sz_res, casadi_int *sz_iw,
                    casadi_int *sz_w);
int wtftc_init_work(casadi_int *sz_arg, casadi_int *sz_res, casadi_int *sz_iw,
                    casadi_int *sz_w);

/* the most of avcMSG ever written, whatever #49 says (a message is shorter) */
#define MSG_MAX 4096
/* the longest line of the input file (longer: refused, unless it is a comment's) */
#define LINE_MAX_IN 4096

typedef struct {
    double p[WTFTC_N_PARAMS];
    double x_ctrl[WTFTC_N_CTRL];
    double x_fdi[WTFTC_N_FDI > 0 ? WTFTC_N_FDI : 1];
    double sched[WTFTC_SCHED_LEN]; /* the ∂T/∂β schedule's runtime table (discon.py) */
    double last[3];     /* the demands written at the last call [rad] (the rate limit) */
    double *w;          /* CasADi work arrays, sized for the larger of the two functions */
    casadi_int *iw;
    const casadi_real **arg;
    casadi_real **res;
} Instance;

static Instance *instance = NULL;

/* avcMSG's capacity in bytes, its NUL included: #49 (ServoDyn sets its message length
 * + 1, ROSCO's ControllerInterface its buffer's); 0 (nothing may be written) when #49 is
 * below 1 or not a number. */
static size_t msg_capacity(const float *avrSWAP)
{
    float given = avrSWAP[48];
    if (!(given >= 1.0f)) return 0;
    return given >= (float)MSG_MAX ? MSG_MAX : (size_t)given;
}

static void fail(int *aviFAIL, char *avcMSG, size_t n_msg, const char *text)
{
    *aviFAIL = -1;
    if (n_msg > 0) snprintf(avcMSG, n_msg, "wtftc %s: %s", WTFTC_CONTROLLER, text);
}

/* A record read as an integer (iStatus, Ptch_Cntrl, a record number); `none` when it is
 * not a finite number of a sane size (a float beyond int's range is undefined in C). */
static int record_int(float v, int none)
{
    return isfinite(v) && fabsf(v) < 1e9f ? (int)lroundf(v) : none;
}

/* v printed in the fewest digits (15 to 17) that read back as v. */
static const char *number(double v, char *buf, size_t n)
{
    for (int digits = 15; digits <= 17; digits++) {
        snprintf(buf, n, "%.*g", digits, v);
        if (strtod(buf, NULL) == v) break;
    }
    return buf;
}

/* Whether path is a regular file of at most max_bytes: -1 with a message otherwise (a
 * folder, a FIFO that would block the open, a device such as /dev/zero, a file too
 * large), before it is opened. */
static int regular_file(const char *path, const char *what, long long max_bytes, char *err,
                        size_t n_err)
{
    struct stat st;
    if (stat(path, &st) != 0) {
        snprintf(err, n_err, "cannot open the %s '%s'", what, path);
        return -1;
    }
    if (!S_ISREG(st.st_mode)) {
        snprintf(err, n_err, "the %s '%s' is not a regular file (a folder, a FIFO or a "
                 "device)", what, path);
        return -1;
    }
    if ((long long)st.st_size > max_bytes) {
        snprintf(err, n_err, "the %s '%s' has %lld bytes: at most %lld are read", what, path,
                 (long long)st.st_size, max_bytes);
        return -1;
    }
    return 0;
}

static void release(void)
{
    if (instance) {
        free(instance->w);
        free(instance->iw);
        free(instance->arg);
        free(instance->res);
        free(instance);
        instance = NULL;
    }
}

/* The parameter named `name`, or -1. */
static int param_index(const char *name)
{
    for (int k = 0; k < WTFTC_N_PARAMS; k++)
        if (strcmp(name, WTFTC_PARAM_NAMES[k]) == 0) return k;
    return -1;
}

/* The Cp file named on a PerfFileName line ("PerfFileName "file" ! comment"), resolved
 * against the input file's folder unless absolute (ROSCO: PriPath // PerfFileName). */
static int cp_name(const char *path, const char *line, int lineno, char *cp, size_t n_cp,
                   char *err, size_t n_err)
{
    const char *s = line + strlen(WTFTC_CP_KEY);
    while (isspace((unsigned char)*s)) s++;
    char quote = (*s == '"' || *s == '\'') ? *s++ : '\0';
    const char *end = s;
    while (*end && (quote ? *end != quote : !isspace((unsigned char)*end) && *end != '!'))
        end++;
    if (end == s || (quote && *end != quote)) {
        snprintf(err, n_err, "%s line %d: %s needs a file name (a quoted path)", path, lineno,
                 WTFTC_CP_KEY);
        return -1;
    }
    size_t dir = 0;
    if (*s != '/' && *s != '\\' && !(isalpha((unsigned char)s[0]) && s[1] == ':'))
        for (size_t k = 0; path[k]; k++)
            if (path[k] == '/' || path[k] == '\\') dir = k + 1;
    if (dir + (size_t)(end - s) + 1 > n_cp) {
        snprintf(err, n_err, "%s line %d: the %s path is too long", path, lineno, WTFTC_CP_KEY);
        return -1;
    }
    memcpy(cp, path, dir);
    memcpy(cp + dir, s, (size_t)(end - s));
    cp[dir + (size_t)(end - s)] = '\0';
    return 0;
}

enum { LINE_OK, LINE_END, LINE_LONG, LINE_NUL };

/* One line of f into buf (the newline dropped, NUL-terminated, at most n - 1 bytes kept):
 * LINE_END at the end of the file, LINE_LONG for a longer line (the rest is skipped),
 * LINE_NUL for a line holding a NUL byte (a binary file). */
static int read_line(FILE *f, char *buf, size_t n)
{
    size_t k = 0;
    int c, got = 0, long_line = 0, nul = 0;
    while ((c = getc(f)) != EOF) {
        got = 1;
        if (c == '\n') break;
        if (c == '\0') nul = 1;
        if (k + 1 < n) buf[k++] = (char)c;
        else long_line = 1;
    }
    buf[k] = '\0';
    return !got ? LINE_END : nul ? LINE_NUL : long_line ? LINE_LONG : LINE_OK;
}

/* Read the input file: lines "name value ! unit - source"; '!' and '#' start comments.
 * Every parameter must be set once, and only known names with finite values (line_of:
 * the line of each); the Cp file once when the controller needs it (cp: its resolved
 * path). */
static int read_input(const char *path, double *p, int *line_of, char *cp, size_t n_cp,
                      char *err, size_t n_err)
{
    if (regular_file(path, "input file", WTFTC_MAX_IN_BYTES, err, n_err) != 0) return -1;
    FILE *f = fopen(path, "r");
    if (!f) {
        snprintf(err, n_err, "cannot open the input file '%s'", path);
        return -1;
    }
    int seen[WTFTC_N_PARAMS] = {0};
    char line[LINE_MAX_IN];
    int lineno = 0, rc = 0, cp_seen = 0, got;
    while (rc == 0 && (got = read_line(f, line, sizeof line)) != LINE_END) {
        lineno++;
        if (got == LINE_NUL) {
            snprintf(err, n_err, "%s line %d: a NUL byte (a text file is needed)", path,
                     lineno);
            rc = -1;
            break;
        }
        if (got == LINE_LONG && !strpbrk(line, "!#")) {
            snprintf(err, n_err, "%s line %d: longer than %d characters", path, lineno,
                     LINE_MAX_IN - 1);
            rc = -1;
            break;
        }
        char key[128];
        if (WTFTC_NEEDS_CP && sscanf(line, "%127s", key) == 1 && strcmp(key, WTFTC_CP_KEY) == 0) {
            if (cp_seen++) {
                snprintf(err, n_err, "%s line %d: %s is set twice", path, lineno, WTFTC_CP_KEY);
                rc = -1;
            } else {
                rc = cp_name(path, strstr(line, WTFTC_CP_KEY), lineno, cp, n_cp, err, n_err);
            }
            continue;
        }
        char *c = strpbrk(line, "!#");
        if (c) *c = '\0';
        char name[128], word[128], rest[128], *end;
        int n = sscanf(line, "%127s %127s %127s", name, word, rest);
        if (n <= 0) continue; /* blank or comment */
        /* the whole word a number (scanf's %lf would take "1.5e" for 1.5) */
        double value = n >= 2 ? strtod(word, &end) : 0.0;
        if (n == 1) {
            snprintf(err, n_err, "%s line %d: %s has no value", path, lineno, name);
            rc = -1;
        } else if (n == 2 && (end == word || *end != '\0')) {
            snprintf(err, n_err, "%s line %d: %s = '%s' is not a number", path, lineno, name,
                     word);
            rc = -1;
        } else if (n == 3) {
            snprintf(err, n_err, "%s line %d: '%s' after the value of %s (a comment starts "
                     "with '!')", path, lineno, rest, name);
            rc = -1;
        } else {
            int k = param_index(name);
            if (k < 0) {
                snprintf(err, n_err, "%s line %d: unknown parameter '%s'", path, lineno,
                         name);
                rc = -1;
            } else if (!isfinite(value)) {
                snprintf(err, n_err, "%s line %d: %s = %g is not finite", path, lineno, name,
                         value);
                rc = -1;
            } else if (seen[k]) {
                snprintf(err, n_err, "%s line %d: %s is set twice", path, lineno, name);
                rc = -1;
            } else {
                p[k] = value;
                seen[k] = 1;
                line_of[k] = lineno;
            }
        }
    }
    fclose(f);
    if (rc == 0 && WTFTC_NEEDS_CP && !cp_seen) {
        snprintf(err, n_err, "%s: %s (the Cp_Ct_Cq file of the dT/dbeta schedule) is missing",
                 path, WTFTC_CP_KEY);
        rc = -1;
    }
    for (int k = 0; rc == 0 && k < WTFTC_N_PARAMS; k++)
        if (!seen[k]) {
            snprintf(err, n_err, "%s: parameter '%s' is missing", path, WTFTC_PARAM_NAMES[k]);
            rc = -1;
        }
    return rc;
}

static int in_range(const WtftcRange *r, double v)
{
    return !(v < r->lo || v > r->hi || (r->lo_open && v == r->lo) || (r->hi_open && v == r->hi));
}

/* Every value against its valid range, then wtftc's cross-checks (wtftc_discon_checks.h,
 * generated from layout.json and wtftc.config): the first refusal in the file's order,
 * naming the line, the parameter, its value and what is allowed. */
static int check_values(const char *path, const double *p, const int *line_of, char *err,
                        size_t n_err)
{
    char a[40], b[40];
    int bad = -1;
    for (int k = 0; k < WTFTC_N_PARAMS; k++)
        if (!in_range(&WTFTC_RANGE[k], p[k]) && (bad < 0 || line_of[k] < line_of[bad]))
            bad = k;
    if (bad >= 0) {
        const WtftcRange *r = &WTFTC_RANGE[bad];
        int degrees = r->angle && in_range(r, p[bad] * (3.141592653589793 / 180.0));
        snprintf(err, n_err, "%s line %d: %s = %s is not allowed: %s%s", path, line_of[bad],
                 WTFTC_PARAM_NAMES[bad], number(p[bad], a, sizeof a), r->allowed,
                 degrees ? " (radians: this looks like degrees)" : "");
        return -1;
    }
    for (int k = 0; k < WTFTC_N_ORDER; k++) {
        int lo = WTFTC_ORDER[k][0], hi = WTFTC_ORDER[k][1];
        if (!(p[lo] < p[hi])) {
            snprintf(err, n_err, "%s line %d: %s = %s is not allowed: %s < %s (here %s = %s)",
                     path, line_of[lo], WTFTC_PARAM_NAMES[lo], number(p[lo], a, sizeof a),
                     WTFTC_PARAM_NAMES[lo], WTFTC_PARAM_NAMES[hi], WTFTC_PARAM_NAMES[hi],
                     number(p[hi], b, sizeof b));
            return -1;
        }
    }
    for (int k = 0; k < WTFTC_N_ONE_OF; k++) {
        const WtftcOneOf *o = &WTFTC_ONE_OF[k];
        if (p[o->k] != o->a && p[o->k] != o->b) {
            snprintf(err, n_err, "%s line %d: %s = %s is not allowed: %s", path,
                     line_of[o->k], WTFTC_PARAM_NAMES[o->k], number(p[o->k], a, sizeof a),
                     o->allowed);
            return -1;
        }
    }
    double rated = p[WTFTC_ENVELOPE_RATED], ref = p[WTFTC_ENVELOPE_REF];
    double low = WTFTC_ENVELOPE_LOW * rated, high = WTFTC_ENVELOPE_HIGH * rated;
    if (!(low < ref && ref < high)) {
        snprintf(err, n_err, "%s line %d: %s = %s is not allowed: a speed inside the operating "
                 "envelope, %.4g-%.4g rad/s (%g-%g x %s; layout.json envelope)", path,
                 line_of[WTFTC_ENVELOPE_REF], WTFTC_PARAM_NAMES[WTFTC_ENVELOPE_REF],
                 number(ref, a, sizeof a), low, high, WTFTC_ENVELOPE_LOW, WTFTC_ENVELOPE_HIGH,
                 WTFTC_PARAM_NAMES[WTFTC_ENVELOPE_RATED]);
        return -1;
    }
    return 0;
}

/* The input file's name: accINFILE up to its length (#50) or its NUL, whichever first
 * (ROSCO's ControllerInterface passes the length without the +1 of the NUL). */
static void input_name(const float *avrSWAP, const char *accINFILE, char *out, size_t n)
{
    int given = record_int(avrSWAP[49], 0);
    size_t len = given > 0 ? (size_t)given : 0;
    size_t k = 0;
    while (k < len && k + 1 < n && accINFILE[k] != '\0') {
        out[k] = accINFILE[k];
        k++;
    }
    out[k] = '\0';
    while (k > 0 && isspace((unsigned char)out[k - 1])) out[--k] = '\0';
}

static int allocate(void)
{
    casadi_int a1, r1, i1, w1, a2, r2, i2, w2;
    wtftc_step_work(&a1, &r1, &i1, &w1);
    wtftc_init_work(&a2, &r2, &i2, &w2);
    instance = calloc(1, sizeof(Instance));
    if (!instance) return -1;
    instance->w = calloc((size_t)(w1 > w2 ? w1 : w2) + 1, sizeof(double));
    instance->iw = calloc((size_t)(i1 > i2 ? i1 : i2) + 1, sizeof(casadi_int));
    instance->arg = calloc((size_t)(a1 > a2 ? a1 : a2) + 1, sizeof(casadi_real *));
    instance->res = calloc((size_t)(r1 > r2 ? r1 : r2) + 1, sizeof(casadi_real *));
    if (!instance->w || !instance->iw || !instance->arg || !instance->res) {
        release();
        return -1;
    }
    return 0;
}

/* The readings of the ten sensors (each quantity's one measurement to both of its
 * sensors), or -1 if one is not finite. */
static int readings(const float *avrSWAP, double *rd, char *err, size_t n_err)
{
    const int records[5] = {21, 20, 4, 33, 34}; /* ω_r, ω_g (HSS), β_1, β_2, β_3 */
    const char *names[5] = {"rotor speed (#21)", "generator speed (#20)",
                            "blade 1 pitch (#4)", "blade 2 pitch (#33)", "blade 3 pitch (#34)"};
    for (int k = 0; k < 5; k++) {
        double v = avrSWAP[records[k] - 1];
        if (!isfinite(v)) {
            snprintf(err, n_err, "the measured %s is %g: a finite value is needed", names[k], v);
            return -1;
        }
        rd[k] = rd[k + 5] = v;
    }
    return 0;
}

/* The tower-top fore-aft acceleration (#53, m/s^2), which only a tower damper reads, or
 * -1 if it is not finite. */
static int tower_acceleration(const float *avrSWAP, double *acc, char *err, size_t n_err)
{
    *acc = avrSWAP[52];
    if (!isfinite(*acc)) {
        snprintf(err, n_err, "the measured tower-top fore-aft acceleration (#53) is %g: a "
                 "finite value is needed", *acc);
        return -1;
    }
    return 0;
}

/* The schedule's runtime table from the Cp file (a flat one when the controller has no
 * schedule): ∂T/∂β at the first breakpoint, then each segment's start, width and slope;
 * unused segments have slope 0 (wtftc/export/discon.py, runtime_schedule). */
static int schedule(const char *cp, char *err, size_t n_err)
{
    double betas[WTFTC_SCHED_MAX], grads[WTFTC_SCHED_MAX];
    int n = 2, m = WTFTC_SCHED_MAX - 1;
    betas[0] = 0.0, betas[1] = 1.0, grads[0] = grads[1] = 0.0;
    if (WTFTC_NEEDS_CP) {
        n = wtftc_schedule_points(cp, instance->p, betas, grads, WTFTC_SCHED_MAX, err, n_err);
        if (n < 0) return -1;
    }
    double *t = instance->sched;
    t[0] = grads[0];
    for (int k = 0; k < m; k++) {
        int used = k < n - 1;
        t[1 + k] = used ? betas[k] : betas[n - 1];
        t[1 + m + k] = used ? betas[k + 1] - betas[k] : 1.0;
        t[1 + 2 * m + k] = used ? (grads[k + 1] - grads[k]) / (betas[k + 1] - betas[k]) : 0.0;
    }
    return 0;
}

static int first_call(float *avrSWAP, const char *accINFILE, char *err, size_t n_err)
{
    char path[1024], cp[2048] = "";
    int line_of[WTFTC_N_PARAMS] = {0};
    release();
    if (allocate() != 0) {
        snprintf(err, n_err, "out of memory");
        return -1;
    }
    input_name(avrSWAP, accINFILE, path, sizeof path);
    if (read_input(path, instance->p, line_of, cp, sizeof cp, err, n_err) != 0) return -1;
    if (check_values(path, instance->p, line_of, err, n_err) != 0) return -1;
    if (schedule(cp, err, n_err) != 0) return -1;
    double dt = avrSWAP[2];
    if (!(fabs(dt - WTFTC_DT) <= 1e-6 * WTFTC_DT)) {
        snprintf(err, n_err, "called every %g s (#3), exported for %g s: set DLL_DT to %g "
                 "or export again with --interval", dt, WTFTC_DT, WTFTC_DT);
        return -1;
    }
    if (record_int(avrSWAP[27], 0) != 1) { /* #28 Ptch_Cntrl */
        snprintf(err, n_err, "Ptch_Cntrl = %g (#28): the accommodation commands each blade "
                 "(#42-#44); set Ptch_Cntrl 1 (individual pitch) in ServoDyn", avrSWAP[27]);
        return -1;
    }
    double rd[WTFTC_N_READINGS], acc;
    if (readings(avrSWAP, rd, err, n_err) != 0) return -1;
    if (tower_acceleration(avrSWAP, &acc, err, n_err) != 0) return -1;
    /* the rate limit starts from where the blades are (#4, #33, #34) */
    instance->last[0] = avrSWAP[3], instance->last[1] = avrSWAP[32],
    instance->last[2] = avrSWAP[33];
    instance->arg[0] = rd;
    instance->arg[1] = instance->p;
    instance->arg[2] = instance->sched;
    instance->arg[3] = &acc;
    instance->res[0] = instance->x_ctrl;
    instance->res[1] = instance->x_fdi;
    if (wtftc_init(instance->arg, instance->res, instance->iw, instance->w, 0) != 0) {
        snprintf(err, n_err, "the initialisation failed");
        return -1;
    }
    for (int k = 0; k < WTFTC_N_CTRL + WTFTC_N_FDI; k++) {
        double x = k < WTFTC_N_CTRL ? instance->x_ctrl[k] : instance->x_fdi[k - WTFTC_N_CTRL];
        if (!isfinite(x)) {
            snprintf(err, n_err, "the initial %s state %d is not finite at t = %g s: check "
                     "the input file's values", k < WTFTC_N_CTRL ? "controller" : "FDI",
                     k < WTFTC_N_CTRL ? k + 1 : k - WTFTC_N_CTRL + 1, avrSWAP[1]);
            return -1;
        }
    }
    return 0;
}

/* The demands as the host gets them: within the turbine's [pitch_min, pitch_max], and,
 * with demand_rate_limit = 1 (a host whose blades follow the demand: no actuator), within
 * pitch_rate_max x the interval of the last call's. The controller and its FDI keep the
 * demand they computed: with the benchmark actuator in the host the position limit is
 * the one wtftc's plant applies to the actuator's input (derivation/turbine.py,
 * commanded_input); without one, the rate limit is what the missing actuator would have
 * limited (docs/discon.md). */
static void limit_demands(double *pitch)
{
    const double *p = instance->p;
    double lo = p[WTFTC_PITCH_MIN], hi = p[WTFTC_PITCH_MAX];
    double step = p[WTFTC_PITCH_RATE_MAX] * WTFTC_DT;
    for (int k = 0; k < 3; k++) {
        double v = pitch[k];
        if (p[WTFTC_DEMAND_RATE_LIMIT] != 0.0) {
            double a = instance->last[k] - step, b = instance->last[k] + step;
            v = v < a ? a : v > b ? b : v;
        }
        pitch[k] = v < lo ? lo : v > hi ? hi : v;
    }
}

/* Whether v converts to a finite float (beyond FLT_MAX the conversion is undefined in C,
 * inf in practice). */
static int as_float(double v)
{
    return isfinite(v) && fabs(v) <= FLT_MAX;
}

static int step(float *avrSWAP, char *err, size_t n_err)
{
    double rd[WTFTC_N_READINGS], pitch[3], torque, logged[WTFTC_N_LOG > 0 ? WTFTC_N_LOG : 1];
    double dt = WTFTC_DT;
    double xc[WTFTC_N_CTRL], xf[WTFTC_N_FDI > 0 ? WTFTC_N_FDI : 1], acc;
    if (readings(avrSWAP, rd, err, n_err) != 0) return -1;
    if (tower_acceleration(avrSWAP, &acc, err, n_err) != 0) return -1;
    instance->arg[0] = rd;
    instance->arg[1] = instance->x_ctrl;
    instance->arg[2] = instance->x_fdi;
    instance->arg[3] = instance->p;
    instance->arg[4] = &dt;
    instance->arg[5] = instance->sched;
    instance->arg[6] = &acc;
    instance->res[0] = pitch;
    instance->res[1] = xc;
    instance->res[2] = xf;
    instance->res[3] = &torque;
    instance->res[4] = logged;
    if (wtftc_step(instance->arg, instance->res, instance->iw, instance->w, 0) != 0) {
        snprintf(err, n_err, "the controller's step failed");
        return -1;
    }
    /* the final guard: every value written is a finite float, or nothing is written */
    static const char *const pitch_records[3] = {"#42", "#43", "#44"};
    for (int k = 0; k < 3; k++)
        if (!as_float(pitch[k])) {
            snprintf(err, n_err, "the pitch demand of blade %d (%s) is %g at t = %g s: not a "
                     "finite float; nothing written", k + 1, pitch_records[k], pitch[k],
                     avrSWAP[1]);
            return -1;
        }
    if (!as_float(torque)) {
        snprintf(err, n_err, "the generator torque demand (#47) is %g at t = %g s: not a "
                 "finite float; nothing written", torque, avrSWAP[1]);
        return -1;
    }
    for (int k = 0; k < WTFTC_N_LOG; k++)
        if (!as_float(logged[k])) {
            snprintf(err, n_err, "the logged channel %d is %g at t = %g s: not a finite "
                     "float; nothing written", k + 1, logged[k], avrSWAP[1]);
            return -1;
        }
    memcpy(instance->x_ctrl, xc, sizeof xc);
    memcpy(instance->x_fdi, xf, sizeof(double) * WTFTC_N_FDI);
    limit_demands(pitch);
    memcpy(instance->last, pitch, sizeof instance->last);
    avrSWAP[41] = (float)pitch[0];
    avrSWAP[42] = (float)pitch[1];
    avrSWAP[43] = (float)pitch[2];
    avrSWAP[44] = (float)pitch[0];
    avrSWAP[46] = (float)torque;
    avrSWAP[34] = 1.0f; /* generator contactor: main generator */
    avrSWAP[35] = 0.0f; /* shaft brake off */
    avrSWAP[54] = 0.0f; /* pitch override: yes */
    avrSWAP[55] = 0.0f; /* torque override: yes */
    avrSWAP[64] = 0.0f;
    int first_log = record_int(avrSWAP[62], 0); /* #63: record of the first logged value */
    if (WTFTC_N_LOG > 0 && first_log >= 1 && first_log - 1 + WTFTC_N_LOG <= WTFTC_SWAP_MAX) {
        for (int k = 0; k < WTFTC_N_LOG; k++) avrSWAP[first_log - 1 + k] = (float)logged[k];
        avrSWAP[64] = (float)WTFTC_N_LOG;
    }
    return 0;
}

#if defined(_WIN32)
#define WTFTC_EXPORT __declspec(dllexport)
#else
#define WTFTC_EXPORT __attribute__((visibility("default")))
#endif

WTFTC_EXPORT void DISCON(float *avrSWAP, int *aviFAIL, const char *accINFILE,
                         char *avcOUTNAME, char *avcMSG)
{
    char err[1200] = "";
    int status = record_int(avrSWAP[0], -1000);
    size_t n_msg = msg_capacity(avrSWAP);
    *aviFAIL = 0;
    if (n_msg > 0) avcMSG[0] = '\0';
    (void)avcOUTNAME; /* an input (the run's root name): never written; the logged
                         channels' names are in README.txt and docs/discon.md */
    if (status == -8 || status == -9) {
        fail(aviFAIL, avcMSG, n_msg, status == -8
                 ? "checkpoints are not supported (iStatus = -8)"
                 : "restarts are not supported (iStatus = -9)");
        return;
    }
    if (status == -1) {
        release();
        return;
    }
    if (status != 0 && status != 1) {
        snprintf(err, sizeof err, "iStatus = %g (#1) is not one of 0, 1, -1", avrSWAP[0]);
        fail(aviFAIL, avcMSG, n_msg, err);
        return;
    }
    if (status == 0 && first_call(avrSWAP, accINFILE, err, sizeof err) != 0) {
        release();
        fail(aviFAIL, avcMSG, n_msg, err);
        return;
    }
    if (!instance) {
        fail(aviFAIL, avcMSG, n_msg, "called with iStatus = 1 before a first call "
                                     "(iStatus = 0) succeeded");
        return;
    }
    if (step(avrSWAP, err, sizeof err) != 0) fail(aviFAIL, avcMSG, n_msg, err);
}
