/* A DISCON library (Bladed's external controller interface, ROSCO's libdiscon.so) called
 * from inside wtftc's compiled loop: a CasADi external function, wtftc_discon, evaluated
 * once per RK4 step, that calls DISCON at the steps flagged as the end of a control
 * interval and otherwise holds the last commands (issue 19: no Python between calls).
 *
 * The library's state is its own (its Fortran module variables) plus the avrSWAP record,
 * held here between calls, as ROSCO's Python ControllerInterface holds it: a float32 array
 * that DISCON's outputs stay in, written field by field before each call
 * (rosco/toolbox/control_interface.py, call_controller). Every double is rounded to float
 * as numpy's astype(float32) rounds it, so the library reads the same bits as through
 * ControllerInterface (tests/test_rosco.py).
 *
 * wtftc_discon_open / _close are called from Python (ctypes, wtftc/sim/rosco.py) around a
 * run; one run at a time per compiled loop library (DISCON's state is process-global).
 */
#include <dlfcn.h>
#include <stdio.h>
#include <string.h>

#ifndef casadi_real
#define casadi_real double
#endif
#ifndef casadi_int
#define casadi_int long long int
#endif

#define WTFTC_AVR_SIZE 2000
#define WTFTC_MSG 1000

typedef void (*wtftc_discon_fn)(float *avr, int *fail, const char *infile,
                                const char *outname, char *msg);

static void *wtftc_lib = NULL;
static wtftc_discon_fn wtftc_call = NULL;
static float wtftc_avr[WTFTC_AVR_SIZE];
static int wtftc_fail = 0;
static char wtftc_infile[4096];
static char wtftc_outname[4096];
static char wtftc_msg[WTFTC_MSG];
static long wtftc_calls = 0;

/* The library at lib, its first call (iStatus = 0) on the initial record init[0..n-1]
 * (index i of init is avrSWAP's C index, as ControllerInterface's avrSWAP). Returns the
 * library's aviFAIL (< 0: it failed; its message from wtftc_discon_message), or -1000 when
 * the library or its DISCON symbol cannot be loaded. */
int wtftc_discon_open(const char *lib, const char *infile, const char *outname,
                      const double *init, int n) {
  int i;
  if (wtftc_lib != NULL) { /* one run at a time */
    snprintf(wtftc_msg, WTFTC_MSG, "a DISCON library is already open in this process "
             "(one ROSCO run at a time)");
    return -1001;
  }
  wtftc_lib = dlopen(lib, RTLD_NOW | RTLD_LOCAL);
  if (wtftc_lib == NULL) {
    snprintf(wtftc_msg, WTFTC_MSG, "%s", dlerror());
    return -1000;
  }
  wtftc_call = (wtftc_discon_fn)dlsym(wtftc_lib, "DISCON");
  if (wtftc_call == NULL) {
    snprintf(wtftc_msg, WTFTC_MSG, "no DISCON symbol in %s", lib);
    dlclose(wtftc_lib);
    wtftc_lib = NULL;
    return -1000;
  }
  snprintf(wtftc_infile, sizeof wtftc_infile, "%s", infile);
  snprintf(wtftc_outname, sizeof wtftc_outname, "%s", outname);
  memset(wtftc_avr, 0, sizeof wtftc_avr);
  for (i = 0; i < n && i < WTFTC_AVR_SIZE; i++) wtftc_avr[i] = (float)init[i];
  wtftc_fail = 0;
  wtftc_msg[0] = 0;
  wtftc_calls = 0;
  wtftc_call(wtftc_avr, &wtftc_fail, wtftc_infile, wtftc_outname, wtftc_msg);
  wtftc_avr[0] = 1.0f; /* not the first call any more */
  return wtftc_fail;
}

/* The last call (iStatus = -1, on the record as it stands), then the library released. */
int wtftc_discon_close(void) {
  if (wtftc_lib == NULL) return 0;
  if (wtftc_calls > 0) {
    wtftc_avr[0] = -1.0f;
    wtftc_call(wtftc_avr, &wtftc_fail, wtftc_infile, wtftc_outname, wtftc_msg);
  }
  dlclose(wtftc_lib);
  wtftc_lib = NULL;
  wtftc_call = NULL;
  return wtftc_fail;
}

const char *wtftc_discon_message(void) { return wtftc_msg; }
long wtftc_discon_calls(void) { return wtftc_calls; }
int wtftc_discon_fail(void) { return wtftc_fail; }

/* The CasADi external function. Inputs: meas (9): flag (1: call at this step), t [s],
 * dt [s], pitch [rad] (measured, the blades' mean), generator speed [rad/s, HSS], rotor
 * speed [rad/s], wind [m/s], generator efficiency [-], the torque last commanded [N m,
 * HSS]; held (4): the last pitch commands [rad] and torque [N m, HSS]. Output: held (4),
 * the new commands at a call, else the input's. */
static const casadi_int wtftc_sp_meas[] = {9, 1, 0, 9, 0, 1, 2, 3, 4, 5, 6, 7, 8};
static const casadi_int wtftc_sp_held[] = {4, 1, 0, 4, 0, 1, 2, 3};

casadi_int wtftc_discon_n_in(void) { return 2; }
casadi_int wtftc_discon_n_out(void) { return 1; }
const char *wtftc_discon_name_in(casadi_int i) { return i == 0 ? "meas" : "held"; }
const char *wtftc_discon_name_out(casadi_int i) { return "held"; }
const casadi_int *wtftc_discon_sparsity_in(casadi_int i) {
  return i == 0 ? wtftc_sp_meas : wtftc_sp_held;
}
const casadi_int *wtftc_discon_sparsity_out(casadi_int i) { return wtftc_sp_held; }
int wtftc_discon_work(casadi_int *sz_arg, casadi_int *sz_res, casadi_int *sz_iw,
                      casadi_int *sz_w) {
  *sz_arg = 2; *sz_res = 1; *sz_iw = 0; *sz_w = 0;
  return 0;
}

int wtftc_discon(const casadi_real **arg, casadi_real **res, casadi_int *iw,
                 casadi_real *w, int mem) {
  const casadi_real *m = arg[0], *h = arg[1];
  casadi_real *out = res[0];
  float *a = wtftc_avr;
  int j;
  (void)iw; (void)w; (void)mem;
  if (out == NULL) return 0;
  if (m == NULL || h == NULL || m[0] == 0.0 || wtftc_call == NULL) {
    for (j = 0; j < 4; j++) out[j] = h ? h[j] : 0.0;
    return 0;
  }
  /* call_controller's writes, in its order (C indices) */
  a[0] = 1.0f;
  a[1] = (float)m[1];
  a[2] = (float)m[2];
  a[3] = (float)m[3];
  a[32] = (float)m[3];
  a[33] = (float)m[3];
  a[14] = (float)(m[4] * m[8] * m[7]); /* gen_speed * gen_torque * gen_eff */
  a[22] = (float)m[8];
  a[19] = (float)m[4];
  a[20] = (float)m[5];
  a[23] = 0.0f;
  a[26] = (float)m[6];
  a[36] = 0.0f;
  a[82] = 0.0f;
  a[52] = 0.0f;
  wtftc_call(a, &wtftc_fail, wtftc_infile, wtftc_outname, wtftc_msg);
  wtftc_calls++;
  for (j = 0; j < 3; j++) out[j] = (casadi_real)a[41 + j]; /* blade pitch demands 42-44 */
  out[3] = (casadi_real)a[46];                              /* generator torque 47 */
  return 0; /* a failure (aviFAIL < 0): wtftc_discon_fail, read after each chunk */
}
