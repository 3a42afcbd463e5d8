/* Time DISCON calls in C (make bench): the library's cost per call without Python.
 * usage: discon_harness LIB INFILE DT SWAP_SIZE N  -> prints ns per call, or an error. */
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

typedef void (*discon_t)(float *, int *, const char *, char *, char *);

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

int main(int argc, char **argv)
{
    if (argc != 6) {
        fprintf(stderr, "usage: %s LIB INFILE DT SWAP_SIZE N\n", argv[0]);
        return 2;
    }
    void *h = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!h) { fprintf(stderr, "%s\n", dlerror()); return 1; }
    discon_t discon = (discon_t)dlsym(h, "DISCON");
    if (!discon) { fprintf(stderr, "no DISCON in %s\n", argv[1]); return 1; }
    int size = atoi(argv[4]), n = atoi(argv[5]), fail = 0;
    double dt = atof(argv[3]);
    float *swap = calloc((size_t)size, sizeof(float));
    char infile[1024], out[1024] = "discon_harness", msg[1024] = "";
    snprintf(infile, sizeof infile, "%s", argv[2]);
    swap[2] = (float)dt; swap[3] = swap[32] = swap[33] = 0.2f;  /* pitch [rad] */
    swap[19] = 122.9f; swap[20] = 1.267f;                        /* speeds */
    swap[22] = 43093.0f; swap[26] = 16.0f;                        /* torque, wind */
    swap[15] = 4.0e6f; swap[49] = (float)strlen(infile); swap[50] = (float)strlen(out);
    swap[27] = 1.0f; swap[28] = 0;                               /* #28 individual pitch */
    swap[128] = 3.0f; swap[61] = 3.0f;                            /* ROSCO: #129, #62 */
    swap[0] = 0; discon(swap, &fail, infile, out, msg);
    if (fail < 0) { fprintf(stderr, "first call: %s\n", msg); return 1; }
    double t0 = now();
    for (int k = 1; k <= n; k++) {
        swap[0] = 1; swap[1] = (float)(k * dt);
        discon(swap, &fail, infile, out, msg);
        if (fail < 0) { fprintf(stderr, "call %d: %s\n", k, msg); return 1; }
    }
    double t1 = now();
    swap[0] = -1; discon(swap, &fail, infile, out, msg);
    printf("%.1f\n", 1e9 * (t1 - t0) / n);
    return 0;
}
