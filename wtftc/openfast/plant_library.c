/* wtftc's plant-side pitch actuator, fault and sensor library for OpenFAST (issue 32).
 *
 * ServoDyn loads this library as its Bladed-style DISCON controller. It loads the real
 * controller library (ROSCO's libdiscon.so, a wtftc export, any DISCON library) and sits
 * between the two without changing either:
 *
 *   OpenFAST --(true speeds)--> sensors --(readings)--> controller --(demands)-->
 *   pitch actuator (with its faults) --(blade pitch)--> OpenFAST
 *
 * - The actuator: each blade's demand drives the turbine's pitch actuator, the
 *   benchmark's second order with its rate and position limits and wtftc's actuator
 *   faults (lock, loss of effectiveness, pressure drop, air in oil, runaway), integrated
 *   by RK4 at a fine step inside each call. Its right-hand side is wtftc's own
 *   (`pitch_actuator`, derived in derivation/turbine.py and generated: the actuator rows
 *   of wtftc's plants), and the fault inputs are built as wtftc.model.faults.Schedule
 *   builds them.
 * - The sensors: every quantity the controller reads (rotor and generator speed, the
 *   three blade pitches) is measured by its two sensors through wtftc's generated sensor
 *   chain (`sensors`: fault, bias, noise, resolution), with the run's noise draws and
 *   sensor faults from a table Python writes; the controller gets the mean of the two.
 * - Records: per call, the time, the demands, the actuator's states, the readings, the
 *   torque demand and the channels the controller logs (#63/#65), to a binary file:
 *   OpenFAST 5.0 does not write a library's logging channels.
 *
 * Records are 1-based in the comments, C index = record - 1 (the Bladed interface:
 * OpenFAST modules/servodyn/src/BladedInterface.f90). A problem sets aviFAIL = -1 with a
 * one-line message (OpenFAST then stops with it); nothing is written to a record from a
 * half-done call.
 */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "wtftc_plant_meta.h"

typedef long long casadi_int;
typedef double casadi_real;
typedef void (*discon_fn)(float *, int *, char *, char *, char *);

int wtftcp_actuator(const casadi_real **arg, casadi_real **res, casadi_int *iw,
                    casadi_real *w, int mem);
int wtftcp_actuator_work(casadi_int *, casadi_int *, casadi_int *, casadi_int *);
int wtftcp_sensors(const casadi_real **arg, casadi_real **res, casadi_int *iw,
                   casadi_real *w, int mem);
int wtftcp_sensors_work(casadi_int *, casadi_int *, casadi_int *, casadi_int *);

#define NB 3               /* blades */
#define NQ (2 + NB)        /* measured quantities: omega_r, omega_g_hss, beta_1..3 */
#define NS (2 * NQ)        /* sensors: two per quantity (m1, m2) */
#define MAX_FAULTS 32
#define LOG_MAX 64
#define PATH_LEN 4096
#define MSG_MAX 1024

enum { F_LOE = 1, F_LOCK = 2, F_HYDRAULIC = 3 };

typedef struct {
    int blade;            /* 0-based */
    int type;
    double onset, end, ramp;
    double a, b;          /* rho | angle (NaN: where the blade is at onset) | omega_n, zeta */
    int bound;            /* a lock at "current": its angle has been read */
} Fault;

typedef struct {
    /* settings */
    char lib_path[PATH_LEN], ctrl_infile[PATH_LEN], records_path[PATH_LEN],
        noise_path[PATH_LEN];
    int actuator_on;
    double dt_a;
    double p_turbine[WTFTCP_N_TURBINE];
    double p_sensors[WTFTCP_N_SENSOR_PARAMS];
    double sensor_faults0[WTFTCP_N_SENSOR_FAULTS];
    int n_noise_cols, n_faults;
    Fault faults[MAX_FAULTS];
    /* state */
    void *lib;
    discon_fn discon;
    double x[2 * NB];     /* beta_1..3, beta_rate_1..3 */
    double u[NB];         /* the demands held since the last call */
    double t0;            /* the first call's time [s] */
    long step;            /* actuator steps since then: the time is t0 + step dt_a, in
                           * double (avrSWAP's time is a float: 0.52 reads 0.51999998) */
    double t_prev;
    long call;
    FILE *records, *noise;
    double *noise_row;
    int n_log;
    /* CasADi work */
    casadi_real *w;
    casadi_int *iw;
    const casadi_real **arg;
    casadi_real **res;
} Plant;

static Plant *plant = NULL;

static size_t msg_capacity(const float *s)
{
    float given = s[48];
    if (!(given >= 1.0f)) return 0;
    return given >= (float)MSG_MAX ? MSG_MAX : (size_t)given;
}

static void fail(int *aviFAIL, char *avcMSG, const float *s, const char *fmt, const char *a,
                 double v)
{
    size_t n = msg_capacity(s);
    *aviFAIL = -1;
    if (n == 0) return;
    char text[MSG_MAX];
    snprintf(text, sizeof text, fmt, a, v);
    snprintf(avcMSG, n, "wtftc plant library: %s", text);
}

static void release(void)
{
    if (!plant) return;
    if (plant->records) fclose(plant->records);
    if (plant->noise) fclose(plant->noise);
    if (plant->lib) dlclose(plant->lib);
    free(plant->noise_row);
    free(plant->w);
    free(plant->iw);
    free(plant->arg);
    free(plant->res);
    free(plant);
    plant = NULL;
}

/* Read n numbers from text into out; the count read. */
static int numbers(const char *text, double *out, int n)
{
    int k = 0;
    char *end;
    while (k < n) {
        double v = strtod(text, &end);
        if (end == text) break;
        out[k++] = v;
        text = end;
    }
    return k;
}

/* The settings file (written by wtftc.openfast.plant_library): "key value..." lines. */
static int read_settings(const char *path, char *err, size_t n_err)
{
    FILE *f = fopen(path, "r");
    if (!f) {
        snprintf(err, n_err, "cannot open its settings file '%s'", path);
        return -1;
    }
    char line[65536];
    int got_turbine = 0, got_sensors = 0, got_sf = 0;
    while (fgets(line, sizeof line, f)) {
        line[strcspn(line, "\r\n")] = 0;
        char *key = line + strspn(line, " \t");
        if (*key == '#' || *key == 0) continue;
        char *val = key + strcspn(key, " \t");
        if (*val) *val++ = 0;
        val += strspn(val, " \t");
        if (strcmp(key, "controller_library") == 0)
            snprintf(plant->lib_path, PATH_LEN, "%s", val);
        else if (strcmp(key, "controller_infile") == 0)
            snprintf(plant->ctrl_infile, PATH_LEN, "%s", val);
        else if (strcmp(key, "records") == 0)
            snprintf(plant->records_path, PATH_LEN, "%s", val);
        else if (strcmp(key, "noise") == 0)
            snprintf(plant->noise_path, PATH_LEN, "%s", val);
        else if (strcmp(key, "noise_columns") == 0)
            plant->n_noise_cols = atoi(val);
        else if (strcmp(key, "actuator") == 0)
            plant->actuator_on = atoi(val);
        else if (strcmp(key, "actuator_dt") == 0)
            plant->dt_a = strtod(val, NULL);
        else if (strcmp(key, "p_turbine") == 0)
            got_turbine = numbers(val, plant->p_turbine, WTFTCP_N_TURBINE);
        else if (strcmp(key, "p_sensors") == 0)
            got_sensors = numbers(val, plant->p_sensors, WTFTCP_N_SENSOR_PARAMS);
        else if (strcmp(key, "sensor_faults") == 0)
            got_sf = numbers(val, plant->sensor_faults0, WTFTCP_N_SENSOR_FAULTS);
        else if (strcmp(key, "fault") == 0) {
            double v[7];
            if (plant->n_faults >= MAX_FAULTS || numbers(val, v, 7) != 7) {
                snprintf(err, n_err, "%s: a fault line needs 7 numbers (at most %d faults)",
                         path, MAX_FAULTS);
                fclose(f);
                return -1;
            }
            Fault *q = &plant->faults[plant->n_faults++];
            q->blade = (int)v[0] - 1;
            q->type = (int)v[1];
            q->onset = v[2], q->end = v[3], q->ramp = v[4], q->a = v[5], q->b = v[6];
            q->bound = !isnan(q->a);
            if (q->blade < 0 || q->blade >= NB || q->type < F_LOE || q->type > F_HYDRAULIC) {
                snprintf(err, n_err, "%s: a fault's blade (1-3) or type (1-3) is wrong", path);
                fclose(f);
                return -1;
            }
        } else {
            snprintf(err, n_err, "%s: unknown key '%s'", path, key);
            fclose(f);
            return -1;
        }
    }
    fclose(f);
    /* a relative path is the settings file's folder's (an export's files lie together) */
    const char *slash = strrchr(path, '/');
    int dir_len = slash ? (int)(slash - path) + 1 : 0;
    char *paths[] = {plant->lib_path, plant->ctrl_infile, plant->records_path,
                     plant->noise_path};
    for (size_t i = 0; i < sizeof paths / sizeof *paths; i++) {
        char joined[PATH_LEN];
        if (!paths[i][0] || paths[i][0] == '/' || dir_len == 0) continue;
        if (snprintf(joined, PATH_LEN, "%.*s%s", dir_len, path, paths[i]) >= PATH_LEN) {
            snprintf(err, n_err, "%s: the path '%s' is too long beside it", path, paths[i]);
            return -1;
        }
        memcpy(paths[i], joined, PATH_LEN);
    }
    if (!plant->lib_path[0] || !plant->records_path[0]) {
        snprintf(err, n_err, "%s names no controller_library or no records file", path);
        return -1;
    }
    if (got_turbine != WTFTCP_N_TURBINE || got_sensors != WTFTCP_N_SENSOR_PARAMS ||
        got_sf != WTFTCP_N_SENSOR_FAULTS) {
        snprintf(err, n_err, "%s: p_turbine, p_sensors or sensor_faults has the wrong "
                 "number of values (%d, %d, %d; expected %d, %d, %d)", path, got_turbine,
                 got_sensors, got_sf, WTFTCP_N_TURBINE, WTFTCP_N_SENSOR_PARAMS,
                 WTFTCP_N_SENSOR_FAULTS);
        return -1;
    }
    if (!(plant->dt_a > 0)) {
        snprintf(err, n_err, "%s: actuator_dt must be > 0", path);
        return -1;
    }
    return 0;
}

/* 0 before onset, 1 while active, linear over ramp at both ends (Fault.weight). */
static double weight(const Fault *q, double t)
{
    if (q->ramp > 0) {
        double up = (t - q->onset) / q->ramp, down = (q->end - t) / q->ramp;
        up = up < 0 ? 0 : up > 1 ? 1 : up;
        down = down < 0 ? 0 : down > 1 ? 1 : down;
        return up < down ? up : down;
    }
    return (t >= q->onset && t < q->end) ? 1.0 : 0.0;
}

/* The actuator fault inputs at t, in the layout's order (Schedule.actuator). */
static void actuator_faults(double t, double *af)
{
    double wn0 = plant->p_turbine[WTFTCP_OMEGA_N_NOMINAL],
           z0 = plant->p_turbine[WTFTCP_ZETA_NOMINAL];
    for (int j = 0; j < NB; j++) {
        af[WTFTCP_AF_RHO + j] = 1.0;
        af[WTFTCP_AF_LOCK + j] = 0.0;
        af[WTFTCP_AF_UBAR + j] = 0.0;
        af[WTFTCP_AF_OMEGA_N + j] = wn0;
        af[WTFTCP_AF_ZETA + j] = z0;
    }
    for (int k = 0; k < plant->n_faults; k++) {
        const Fault *q = &plant->faults[k];
        int j = q->blade;
        double w = weight(q, t);
        if (q->type == F_LOE) {
            af[WTFTCP_AF_RHO + j] = af[WTFTCP_AF_RHO + j] * (1 - w) + q->a * w;
        } else if (q->type == F_LOCK) {
            if (w > af[WTFTCP_AF_LOCK + j]) af[WTFTCP_AF_LOCK + j] = w;
            if (w > 0) af[WTFTCP_AF_UBAR + j] = q->a;
        } else {
            af[WTFTCP_AF_OMEGA_N + j] = af[WTFTCP_AF_OMEGA_N + j] * (1 - w) + q->a * w;
            af[WTFTCP_AF_ZETA + j] = af[WTFTCP_AF_ZETA + j] * (1 - w) + q->b * w;
        }
    }
}

static void actuator_rate(const double *x, const double *af, double *dx)
{
    plant->arg[0] = x;
    plant->arg[1] = plant->u;
    plant->arg[2] = af;
    plant->arg[3] = plant->p_turbine;
    plant->res[0] = dx;
    wtftcp_actuator(plant->arg, plant->res, plant->iw, plant->w, 0);
}

/* One RK4 step of the actuators from t with the demands and fault inputs held. */
static void actuator_step(double t)
{
    double af[WTFTCP_N_ACT_FAULTS], k1[2 * NB], k2[2 * NB], k3[2 * NB], k4[2 * NB],
        y[2 * NB], h = plant->dt_a;
    actuator_faults(t, af);
    actuator_rate(plant->x, af, k1);
    for (int i = 0; i < 2 * NB; i++) y[i] = plant->x[i] + 0.5 * h * k1[i];
    actuator_rate(y, af, k2);
    for (int i = 0; i < 2 * NB; i++) y[i] = plant->x[i] + 0.5 * h * k2[i];
    actuator_rate(y, af, k3);
    for (int i = 0; i < 2 * NB; i++) y[i] = plant->x[i] + h * k3[i];
    actuator_rate(y, af, k4);
    for (int i = 0; i < 2 * NB; i++)
        plant->x[i] += h / 6.0 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]);
}

/* A lock "wherever the blade is" whose onset falls before t1, the end of the control
 * interval that starts now, takes its blade's angle now, at the start of that interval
 * (as wtftc's sampled loop binds it: Schedule.bind_current_angles). */
static void bind_locks(double t1)
{
    for (int k = 0; k < plant->n_faults; k++) {
        Fault *q = &plant->faults[k];
        if (q->type == F_LOCK && !q->bound && q->onset < t1 - 1e-12) {
            q->a = plant->x[q->blade];
            q->bound = 1;
        }
    }
}

/* The readings handed to the controller: every quantity's two sensors through wtftc's
 * sensor chain, averaged. true_q: omega_r, omega_g_hss, beta_1..3. */
static int readings(const double *true_q, double *out, char *err, size_t n_err)
{
    double truth[NS], noise[NS], meas[NS], lag_dot[NS];
    const double *sf = plant->sensor_faults0;
    for (int i = 0; i < NS; i++) truth[i] = true_q[i % NQ];
    for (int i = 0; i < NS; i++) noise[i] = 0.0;
    if (plant->noise) {
        if (fread(plant->noise_row, sizeof(double), (size_t)plant->n_noise_cols,
                  plant->noise) != (size_t)plant->n_noise_cols) {
            snprintf(err, n_err, "its noise table '%s' ended at call %ld (t = %g s): the "
                     "run is longer than the table", plant->noise_path, plant->call,
                     plant->t_prev);
            return -1;
        }
        for (int i = 0; i < NS; i++) noise[i] = plant->noise_row[i];
        if (plant->n_noise_cols >= NS + WTFTCP_N_SENSOR_FAULTS) sf = plant->noise_row + NS;
    }
    plant->arg[0] = truth;
    plant->arg[1] = truth; /* the lag states: no lag (refused by wtftc before the run) */
    plant->arg[2] = noise;
    plant->arg[3] = sf;
    plant->arg[4] = plant->p_sensors;
    plant->res[0] = meas;
    plant->res[1] = lag_dot;
    wtftcp_sensors(plant->arg, plant->res, plant->iw, plant->w, 0);
    for (int q = 0; q < NQ; q++) out[q] = 0.5 * (meas[q] + meas[q + NQ]);
    return 0;
}

static int open_plant(float *s, char *infile, char *err, size_t n_err)
{
    plant = calloc(1, sizeof *plant);
    if (!plant) {
        snprintf(err, n_err, "out of memory");
        return -1;
    }
    plant->actuator_on = 1;
    plant->dt_a = 0.001;
    if (read_settings(infile, err, n_err)) return -1;
    plant->lib = dlopen(plant->lib_path, RTLD_NOW | RTLD_LOCAL);
    if (!plant->lib) {
        snprintf(err, n_err, "cannot load the controller library '%s': %s", plant->lib_path,
                 dlerror());
        return -1;
    }
    plant->discon = (discon_fn)dlsym(plant->lib, "DISCON");
    if (!plant->discon) {
        snprintf(err, n_err, "the controller library '%s' has no DISCON", plant->lib_path);
        return -1;
    }
    casadi_int a1, r1, i1, w1, a2, r2, i2, w2;
    wtftcp_actuator_work(&a1, &r1, &i1, &w1);
    wtftcp_sensors_work(&a2, &r2, &i2, &w2);
    plant->arg = calloc((size_t)(a1 > a2 ? a1 : a2), sizeof *plant->arg);
    plant->res = calloc((size_t)(r1 > r2 ? r1 : r2), sizeof *plant->res);
    plant->iw = calloc((size_t)(i1 > i2 ? i1 : i2) + 1, sizeof *plant->iw);
    plant->w = calloc((size_t)(w1 > w2 ? w1 : w2) + 1, sizeof *plant->w);
    if (!plant->arg || !plant->res || !plant->iw || !plant->w) {
        snprintf(err, n_err, "out of memory");
        return -1;
    }
    if (plant->noise_path[0]) {
        plant->noise = fopen(plant->noise_path, "rb");
        plant->noise_row = calloc((size_t)plant->n_noise_cols + 1, sizeof(double));
        if (!plant->noise || plant->n_noise_cols < NS) {
            snprintf(err, n_err, "cannot read its noise table '%s' (%d columns)",
                     plant->noise_path, plant->n_noise_cols);
            return -1;
        }
    }
    plant->records = fopen(plant->records_path, "wb");
    if (!plant->records) {
        snprintf(err, n_err, "cannot write its records file '%s'", plant->records_path);
        return -1;
    }
    for (int j = 0; j < NB; j++) {
        plant->x[j] = (double)s[j == 0 ? 3 : 31 + j];  /* #4, #33, #34 */
        plant->x[NB + j] = 0.0;
        plant->u[j] = plant->x[j];
    }
    plant->t0 = plant->t_prev = (double)s[1];
    return 0;
}

static int pitch_record(int j) { return j == 0 ? 3 : 31 + j; }  /* #4, #33, #34 */

__attribute__((visibility("default")))
void DISCON(float *avrSWAP, int *aviFAIL, char *accINFILE, char *avcOUTNAME, char *avcMSG)
{
    float *s = avrSWAP;
    char err[MSG_MAX] = "";
    int status = (int)lroundf(s[0]);
    *aviFAIL = 0;
    if (status == 0) {
        release();
        char infile[PATH_LEN];
        int n = (int)lroundf(s[49]);
        if (n <= 0 || n >= PATH_LEN) n = (int)strnlen(accINFILE, PATH_LEN - 1);
        memcpy(infile, accINFILE, (size_t)n);
        infile[n] = 0;
        if (open_plant(s, infile, err, sizeof err)) {
            fail(aviFAIL, avcMSG, s, "%s", err, 0);
            fprintf(stderr, "wtftc plant library: %s\n", err);
            release();
            return;
        }
    } else if (!plant) {
        fail(aviFAIL, avcMSG, s, "called with iStatus %s%g before its first call", "",
             (double)status);
        return;
    }
    /* the actuators from the last call to now, the demands held */
    double span = (double)s[1] - plant->t_prev;
    long n = status == 0 ? 0 : lround(span / plant->dt_a);
    if (n < 0 || fabs(n * plant->dt_a - span) > 0.25 * plant->dt_a) { /* a float time */
        fail(aviFAIL, avcMSG, s, "the call interval%s %g s is not a whole number of its "
             "actuator steps", "", span);
        return;
    }
    double t = plant->t0 + (plant->step + n) * plant->dt_a;
    if (plant->actuator_on) {
        bind_locks(t);
        for (long i = 0; i < n; i++)
            actuator_step(plant->t0 + (plant->step + i) * plant->dt_a);
    } else if (status != 0) {
        for (int j = 0; j < NB; j++) plant->x[j] = plant->u[j];
    }
    plant->step += n;
    plant->t_prev = (double)s[1];
    /* the controller's readings */
    double true_q[NQ] = {(double)s[20], (double)s[19], plant->x[0], plant->x[1], plant->x[2]};
    double read[NQ];
    if (readings(true_q, read, err, sizeof err)) {
        fail(aviFAIL, avcMSG, s, "%s", err, 0);
        return;
    }
    s[20] = (float)read[0];
    s[19] = (float)read[1];
    for (int j = 0; j < NB; j++) s[pitch_record(j)] = (float)read[2 + j];
    /* the controller, on its own input file */
    float n_in = s[49];
    s[49] = (float)strlen(plant->ctrl_infile);
    plant->discon(s, aviFAIL, plant->ctrl_infile, avcOUTNAME, avcMSG);
    s[49] = n_in;
    if (*aviFAIL < 0) return; /* its message stands */
    int individual = (int)lroundf(s[27]) == 1;
    for (int j = 0; j < NB; j++) {
        double d = (double)s[individual ? 41 + j : 44];
        if (isfinite(d)) plant->u[j] = d;
    }
    /* the blades where the actuators hold them now */
    for (int j = 0; j < NB; j++) s[41 + j] = (float)plant->x[j];
    s[44] = (float)plant->x[0];
    /* the records */
    int n_log = (int)lroundf(s[64]), first = (int)lroundf(s[62]);
    if (plant->call == 0) {
        plant->n_log = (n_log > 0 && first >= 1 && n_log <= LOG_MAX) ? n_log : 0;
        fprintf(plant->records, "wtftc plant records 1 columns %d logged %d\n",
                16 + plant->n_log, plant->n_log);
    }
    double row[16 + LOG_MAX];
    row[0] = t;
    for (int j = 0; j < NB; j++) {
        row[1 + j] = plant->u[j];
        row[4 + j] = plant->x[j];
        row[7 + j] = plant->x[NB + j];
    }
    for (int q = 0; q < NQ; q++) row[10 + q] = read[q];
    row[15] = (double)s[46];
    for (int k = 0; k < plant->n_log; k++)
        row[16 + k] = (n_log == plant->n_log && first >= 1) ? (double)s[first - 1 + k] : NAN;
    fwrite(row, sizeof(double), (size_t)(16 + plant->n_log), plant->records);
    plant->call++;
    if (status < 0) release();
}
