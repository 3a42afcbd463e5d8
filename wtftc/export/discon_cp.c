/* The rotor performance table of a wtftc DISCON library, read at load time, and the
 * ∂T_aero/∂β gain schedule computed from it (wtftc export discon).
 *
 * The table is a Cp_Ct_Cq file in ROSCO's text format (rosco.toolbox.utilities.
 * write_rotor_performance; read as ROSCO's ReadSetParameters.f90 ReadCpFile reads it):
 * '#' header lines name the sections "Pitch angle vector" [deg], "TSR vector" [-] and
 * "Power coefficient" (rows: TSR, columns: pitch); other sections are skipped. The file
 * is named by PerfFileName in the input file, relative to the input file's folder
 * (ROSCO's ReadSetParameters.f90: PriPath // PerfFileName when the path is relative).
 *
 * The schedule is wtftc.model.aero.schedule_points, step for step: Cp(λ, β) is the
 * tensor-product not-a-knot cubic interpolating spline of the table (what CasADi's
 * "bspline" interpolant is), λ clipped to the grid; for each table pitch β_k ≥ 0 the
 * wind at which rated speed and rated torque balance (bisection on 3-45 m/s, as
 * wtftc.model.cp_table.bisect), then ∂T_aero/∂β there with ∂Cp/∂β of the spline. The
 * turbine's side (λ = ω R / v, T_aero and ∂T_aero/∂β) is generated: wtftc_sched_tsr and
 * wtftc_sched_point, from the same aero_torque_sensitivity the simulator uses.
 *
 * At a table pitch β_k the tensor spline reduces to 1-D splines: Cp(λ, β_k) is the
 * λ-spline through the column Cp(·, β_k), and ∂Cp/∂β(λ, β_k) the λ-spline through the
 * β-derivatives at β_k of the β-splines through each row.
 */
#define _POSIX_C_SOURCE 200809L /* stat() and S_ISREG under -std=c99 */
#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "wtftc_discon_meta.h"

typedef long long casadi_int;
typedef double casadi_real;
int wtftc_sched_tsr(const casadi_real **arg, casadi_real **res, casadi_int *iw,
                    casadi_real *w, int mem);
int wtftc_sched_point(const casadi_real **arg, casadi_real **res, casadi_int *iw,
                      casadi_real *w, int mem);

#define GRID_MAX 1000
#define WTFTC_PI 3.141592653589793238462643383279502884 /* numpy deg2rad: x * (pi / 180) */
#define V_LO 3.0
#define V_HI 45.0

typedef struct {
    int n_pitch, n_tsr;
    double pitch[GRID_MAX], tsr[GRID_MAX]; /* [rad], [-] */
    double *cp;                            /* n_tsr x n_pitch, row-major */
} CpTable;

enum { SEC_NONE, SEC_PITCH, SEC_TSR, SEC_CP, SEC_OTHER };

/* Case-insensitive substring test. */
static int has(const char *line, const char *word)
{
    size_t n = strlen(word);
    for (; *line; line++) {
        size_t k = 0;
        while (k < n && line[k] && tolower((unsigned char)line[k]) == word[k]) k++;
        if (k == n) return 1;
    }
    return 0;
}

static int section_of(const char *line)
{
    if (has(line, "pitch angle vector")) return SEC_PITCH;
    if (has(line, "tsr vector")) return SEC_TSR;
    if (has(line, "power coef")) return SEC_CP;
    if (has(line, "wind speed vector") || has(line, "thrust coef") || has(line, "torque coef"))
        return SEC_OTHER;
    return SEC_NONE;
}

/* The numbers of one line into out[*n..], at most cap; -1 on a token that is no number. */
static int numbers(char *line, double *out, int *n, int cap, int *overflow)
{
    char *s = line;
    for (;;) {
        while (isspace((unsigned char)*s)) s++;
        if (!*s) return 0;
        char *end;
        double v = strtod(s, &end);
        if (end == s || !isfinite(v) || (*end && !isspace((unsigned char)*end))) return -1;
        if (*n < cap) out[*n] = v;
        else *overflow = 1;
        (*n)++;
        s = end;
    }
}

static char *slurp(const char *path, char *err, size_t n_err)
{
    struct stat st; /* a regular file under the cap: a FIFO would block the open */
    if (stat(path, &st) == 0 && (!S_ISREG(st.st_mode) || st.st_size > WTFTC_MAX_CP_BYTES)) {
        snprintf(err, n_err, "the Cp file '%s' is not a regular file of at most %lld bytes "
                 "(a folder, a FIFO, a device or too large)", path,
                 (long long)WTFTC_MAX_CP_BYTES);
        return NULL;
    }
    FILE *f = fopen(path, "rb");
    if (!f) {
        snprintf(err, n_err, "cannot open the Cp file '%s' (PerfFileName, relative to the "
                 "input file's folder)", path);
        return NULL;
    }
    fseek(f, 0, SEEK_END);
    long size = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *text = size >= 0 && size <= WTFTC_MAX_CP_BYTES ? malloc((size_t)size + 1) : NULL;
    if (!text || fread(text, 1, (size_t)size, f) != (size_t)size) {
        snprintf(err, n_err, "cannot read the Cp file '%s'", path);
        free(text);
        fclose(f);
        return NULL;
    }
    text[size] = '\0';
    fclose(f);
    return text;
}

/* Check the grids once read: strictly increasing, at least 4 points (a not-a-knot
 * cubic), within GRID_MAX. */
static int check_grid(const char *path, const char *name, const double *v, int n,
                      int overflow, char *err, size_t n_err)
{
    if (overflow || n < 4) {
        snprintf(err, n_err, "%s: the '%s' has %d entries: 4 to %d are needed", path, name, n,
                 GRID_MAX);
        return -1;
    }
    for (int k = 1; k < n; k++)
        if (!(v[k] > v[k - 1])) {
            snprintf(err, n_err, "%s: the '%s' is not strictly increasing (%g then %g)", path,
                     name, v[k - 1], v[k]);
            return -1;
        }
    return 0;
}

/* Read the table's pitch and TSR grids and Cp matrix; -1 with a message naming the file
 * and line on any defect. */
int wtftc_read_cp(const char *path, CpTable *t, char *err, size_t n_err)
{
    char *text = slurp(path, err, n_err);
    if (!text) return -1;
    double *rows = malloc(sizeof(double) * GRID_MAX * GRID_MAX / 4);
    int cap_cp = GRID_MAX * GRID_MAX / 4, n_cp = 0, cp_rows = 0, row_len = -1;
    int sec = SEC_NONE, lineno = 0, rc = 0, over_p = 0, over_t = 0, over_c = 0;
    int seen[5] = {0};
    t->n_pitch = t->n_tsr = 0;
    char *line = text;
    while (rc == 0 && line && *line) {
        char *next = strchr(line, '\n');
        if (next) *next++ = '\0';
        lineno++;
        char *s = line;
        while (isspace((unsigned char)*s)) s++;
        if (*s == '#') {
            sec = section_of(s);
            if (sec != SEC_NONE && sec != SEC_OTHER && seen[sec]++) {
                snprintf(err, n_err, "%s line %d: a second '%s' section", path, lineno, s + 1);
                rc = -1;
            }
        } else if (*s) {
            int n = 0, bad = 0;
            double dummy;
            if (sec == SEC_PITCH) bad = numbers(s, t->pitch, &t->n_pitch, GRID_MAX, &over_p);
            else if (sec == SEC_TSR) bad = numbers(s, t->tsr, &t->n_tsr, GRID_MAX, &over_t);
            else if (sec == SEC_CP) {
                int before = n_cp;
                bad = rows ? numbers(s, rows, &n_cp, cap_cp, &over_c) : -1;
                if (!bad && row_len < 0) row_len = n_cp - before;
                if (!bad && n_cp - before != row_len) {
                    snprintf(err, n_err, "%s line %d: a Power coefficient row of %d values "
                             "after rows of %d", path, lineno, n_cp - before, row_len);
                    rc = -1;
                }
                cp_rows++;
            } else if (sec == SEC_OTHER) {
                int ignored = 0; /* wind, Ct, Cq: not needed */
                bad = numbers(s, &dummy, &n, 0, &ignored);
            }
            else {
                snprintf(err, n_err, "%s line %d: numbers under no section header ('# Pitch "
                         "angle vector', '# TSR vector', '# Power coefficient')", path, lineno);
                rc = -1;
            }
            if (rc == 0 && bad) {
                snprintf(err, n_err, "%s line %d: an entry that is not a finite number", path,
                         lineno);
                rc = -1;
            }
        }
        line = next;
    }
    free(text);
    if (rc == 0 && !(seen[SEC_PITCH] && seen[SEC_TSR] && seen[SEC_CP])) {
        snprintf(err, n_err, "%s: no '%s' section (a Cp_Ct_Cq file in ROSCO's format is "
                 "needed)", path, !seen[SEC_PITCH] ? "Pitch angle vector"
                 : !seen[SEC_TSR] ? "TSR vector" : "Power coefficient");
        rc = -1;
    }
    if (rc == 0) rc = check_grid(path, "Pitch angle vector", t->pitch, t->n_pitch, over_p,
                                 err, n_err);
    if (rc == 0) rc = check_grid(path, "TSR vector", t->tsr, t->n_tsr, over_t, err, n_err);
    if (rc == 0 && (over_c || cp_rows != t->n_tsr || row_len != t->n_pitch)) {
        snprintf(err, n_err, "%s: the Power coefficient matrix is %d x %d: %d rows (one per "
                 "TSR) x %d columns (one per pitch) are needed", path, cp_rows, row_len,
                 t->n_tsr, t->n_pitch);
        rc = -1;
    }
    if (rc != 0) {
        free(rows);
        return -1;
    }
    for (int k = 0; k < t->n_pitch; k++) t->pitch[k] = t->pitch[k] * (WTFTC_PI / 180.0);
    t->cp = rows;
    return 0;
}

/* The second derivatives m[0..n-1] of the not-a-knot cubic spline through (x, y), n ≥ 4
 * (dense elimination with partial pivoting: the tables are small and this runs once). */
static void spline_m(const double *x, const double *y, int n, double *m, double *a)
{
    memset(a, 0, sizeof(double) * (size_t)n * (size_t)(n + 1));
#define A(i, j) a[(size_t)(i) * (size_t)(n + 1) + (size_t)(j)]
    for (int i = 1; i < n - 1; i++) {
        double h0 = x[i] - x[i - 1], h1 = x[i + 1] - x[i];
        A(i, i - 1) = h0;
        A(i, i) = 2.0 * (h0 + h1);
        A(i, i + 1) = h1;
        A(i, n) = 6.0 * ((y[i + 1] - y[i]) / h1 - (y[i] - y[i - 1]) / h0);
    }
    double h0 = x[1] - x[0], h1 = x[2] - x[1]; /* m''' continuous at x[1] */
    A(0, 0) = h1;
    A(0, 1) = -(h0 + h1);
    A(0, 2) = h0;
    double g0 = x[n - 2] - x[n - 3], g1 = x[n - 1] - x[n - 2]; /* and at x[n-2] */
    A(n - 1, n - 3) = g1;
    A(n - 1, n - 2) = -(g0 + g1);
    A(n - 1, n - 1) = g0;
    for (int c = 0; c < n; c++) {
        int p = c;
        for (int r = c + 1; r < n; r++)
            if (fabs(A(r, c)) > fabs(A(p, c))) p = r;
        for (int j = 0; j <= n; j++) {
            double s = A(c, j);
            A(c, j) = A(p, j);
            A(p, j) = s;
        }
        for (int r = c + 1; r < n; r++) {
            double f = A(r, c) / A(c, c);
            for (int j = c; j <= n; j++) A(r, j) -= f * A(c, j);
        }
    }
    for (int r = n - 1; r >= 0; r--) {
        double s = A(r, n);
        for (int j = r + 1; j < n; j++) s -= A(r, j) * m[j];
        m[r] = s / A(r, r);
    }
#undef A
}

/* The spline (m from spline_m) or its derivative at u, u clipped to [x[0], x[n-1]]. */
static double spline_at(const double *x, const double *y, const double *m, int n, double u,
                        int derivative)
{
    u = fmin(fmax(u, x[0]), x[n - 1]);
    int i = 0;
    while (i < n - 2 && u > x[i + 1]) i++;
    double h = x[i + 1] - x[i], l = x[i + 1] - u, r = u - x[i];
    double c0 = y[i] / h - m[i] * h / 6.0, c1 = y[i + 1] / h - m[i + 1] * h / 6.0;
    if (derivative)
        return -m[i] * l * l / (2.0 * h) + m[i + 1] * r * r / (2.0 * h) - c0 + c1;
    return m[i] * l * l * l / (6.0 * h) + m[i + 1] * r * r * r / (6.0 * h) + c0 * l + c1 * r;
}

typedef struct {
    const CpTable *t;
    const double *col, *col_m, *dcol, *dcol_m; /* Cp(·, β_k), ∂Cp/∂β(·, β_k), their m */
    const double *p;
    double beta;
} Point;

/* T_aero - rated torque at wind v (out[0]) and ∂T_aero/∂β (out[1]) on the operating
 * curve at the point's pitch. */
static void evaluate(const Point *q, double v, double *out)
{
    double tsr;
    casadi_int iw[WTFTC_SCHED_IW + 1];
    double w[WTFTC_SCHED_W + 1];
    const double *arg[WTFTC_SCHED_ARG + 1] = {&v, q->p};
    double *res[WTFTC_SCHED_RES + 1] = {&tsr};
    wtftc_sched_tsr(arg, res, iw, w, 0);
    double cp = spline_at(q->t->tsr, q->col, q->col_m, q->t->n_tsr, tsr, 0);
    double dcp = spline_at(q->t->tsr, q->dcol, q->dcol_m, q->t->n_tsr, tsr, 0);
    const double *arg2[WTFTC_SCHED_ARG + 1] = {&q->beta, &v, &cp, &dcp, q->p};
    double *res2[WTFTC_SCHED_RES + 1] = {&out[0], &out[1]};
    wtftc_sched_point(arg2, res2, iw, w, 0);
}

static double excess(const Point *q, double v)
{
    double out[2];
    evaluate(q, v, out);
    return out[0];
}

/* wtftc.model.cp_table.bisect(not excess > 0, 3, 45): 60 halvings or down to adjacent
 * floats. */
static double balance_wind(const Point *q)
{
    double lo = V_LO, hi = V_HI;
    for (int k = 0; k < 60; k++) {
        double mid = 0.5 * (lo + hi);
        if (mid == lo || mid == hi) break;
        if (!(excess(q, mid) > 0)) lo = mid;
        else hi = mid;
    }
    return 0.5 * (lo + hi);
}

/* The schedule's breakpoints (pitch [rad], ∂T_aero/∂β [N m/rad]) from the table at path
 * and the parameter vector p: their number, or -1 with a message. */
int wtftc_schedule_points(const char *path, const double *p, double *betas, double *grads,
                          int n_max, char *err, size_t n_err)
{
    CpTable *t = malloc(sizeof(CpTable));
    if (!t) {
        snprintf(err, n_err, "out of memory");
        return -1;
    }
    if (wtftc_read_cp(path, t, err, n_err) != 0) {
        free(t);
        return -1;
    }
    int np = t->n_pitch, nt = t->n_tsr, nmax = np > nt ? np : nt, count = 0;
    double *a = malloc(sizeof(double) * (size_t)nmax * (size_t)(nmax + 1));
    double *row_m = malloc(sizeof(double) * (size_t)nt * (size_t)np);
    double *col = malloc(sizeof(double) * 4 * (size_t)nt);
    for (int i = 0; a && row_m && col && i < nt; i++)
        spline_m(t->pitch, t->cp + (size_t)i * np, np, row_m + (size_t)i * np, a);
    for (int k = 0; a && row_m && col && k < np; k++) {
        if (t->pitch[k] < 0) continue;
        Point q = {t, col, col + nt, col + 2 * nt, col + 3 * nt, p, t->pitch[k]};
        for (int i = 0; i < nt; i++) {
            col[i] = t->cp[(size_t)i * np + k];
            col[2 * nt + i] = spline_at(t->pitch, t->cp + (size_t)i * np,
                                        row_m + (size_t)i * np, np, t->pitch[k], 1);
        }
        spline_m(t->tsr, col, nt, col + nt, a);
        spline_m(t->tsr, col + 2 * nt, nt, col + 3 * nt, a);
        if (excess(&q, V_LO) > 0 || excess(&q, V_HI) < 0) continue;
        double out[2];
        evaluate(&q, balance_wind(&q), out);
        if (count == n_max) {
            snprintf(err, n_err, "%s: more than %d pitch angles >= 0 on the operating curve: "
                     "thin the table's pitch grid", path, n_max);
            count = -1;
            break;
        }
        betas[count] = t->pitch[k];
        grads[count++] = out[1];
    }
    if (!a || !row_m || !col) {
        snprintf(err, n_err, "out of memory");
        count = -1;
    } else if (count >= 0 && count < 2) {
        snprintf(err, n_err, "%s: the table has no above-rated operating range at this "
                 "turbine's rated speed and torque for winds of 3-45 m/s (%d pitch angle(s) "
                 "balance): check the table and turbine_params", path, count);
        count = -1;
    }
    free(a);
    free(row_m);
    free(col);
    free(t->cp);
    free(t);
    return count;
}
