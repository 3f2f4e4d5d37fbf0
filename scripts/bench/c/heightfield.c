/* The anchor for scripts/bench/removal: a flat-tool height-field
 * cut (row interval of the swept capsule, then a plain
 * minimum over it), written as plain single-threaded C. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

static void interval(double y, double ax, double ay, double bx, double by, double r, double *lo, double *hi) {
    double len = hypot(bx - ax, by - ay), ux = (bx - ax) / len, uy = (by - ay) / len;
    *lo = INFINITY; *hi = -INFINITY;
    double cs[2][2] = {{ax, ay}, {bx, by}};
    for (int k = 0; k < 2; k++) {
        double e = y - cs[k][1];
        if (fabs(e) <= r) { double w = sqrt(r * r - e * e); if (cs[k][0] - w < *lo) *lo = cs[k][0] - w; if (cs[k][0] + w > *hi) *hi = cs[k][0] + w; }
    }
    double ey = y - ay, c0 = ux * ey, d0 = uy * ey, cl, ch, dl, dh;
    if (uy == 0) { if (fabs(c0) > r) return; cl = -INFINITY; ch = INFINITY; }
    else { double p = (c0 - r) / uy, q = (c0 + r) / uy; cl = fmin(p, q); ch = fmax(p, q); }
    if (ux == 0) { if (d0 < 0 || d0 > len) return; dl = -INFINITY; dh = INFINITY; }
    else { double p = -d0 / ux, q = (len - d0) / ux; dl = fmin(p, q); dh = fmax(p, q); }
    double l = fmax(cl, dl), h = fmin(ch, dh);
    if (l <= h) { if (ax + l < *lo) *lo = ax + l; if (ax + h > *hi) *hi = ax + h; }
}

int main(int argc, char **argv) {
    int moves = argc > 1 ? atoi(argv[1]) : 2000;
    double res = 0.01, r = 2.0;
    int nx = 2000, ny = 2000;
    float *h = malloc(sizeof(float) * nx * ny);
    for (int i = 0; i < nx * ny; i++) h[i] = 0.0f;
    unsigned long long updates = 0;
    double removed = 0;
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    for (int k = 0; k < moves; k++) {
        double y = 2.0 + 16.0 * fmod(k * 0.381966, 1.0), z = -0.001 * (k + 1.0);
        double a = k % 2 == 0 ? 2.0 : 18.0, b = k % 2 == 0 ? 18.0 : 2.0;
        int j0 = (int)ceil((y - r) / res - 0.5), j1 = (int)floor((y + r) / res - 0.5);
        if (j0 < 0) j0 = 0; if (j1 > ny - 1) j1 = ny - 1;
        float zf = (float)z;
        for (int j = j0; j <= j1; j++) {
            double lo, hi, yc = (j + 0.5) * res;
            interval(yc, a, y, b, y, r, &lo, &hi);
            if (lo > hi) continue;
            int i0 = (int)ceil(lo / res - 0.5), i1 = (int)floor(hi / res - 0.5);
            if (i0 < 0) i0 = 0; if (i1 > nx - 1) i1 = nx - 1;
            float *row = h + (size_t)j * nx;
            double s = 0;
            for (int i = i0; i <= i1; i++) { float d = row[i] - zf; s += d > 0 ? d : 0; row[i] = row[i] < zf ? row[i] : zf; }
            removed += s;
        }
        updates += (unsigned long long)((16.0 * 4.0 + M_PI * 4.0) / (res * res));
    }
    clock_gettime(CLOCK_MONOTONIC, &t1);
    double secs = (t1.tv_sec - t0.tv_sec) + (t1.tv_nsec - t0.tv_nsec) * 1e-9;
    printf("{\"moves\":%d,\"cell_updates\":%llu,\"seconds\":%.4f,\"cell_updates_per_s\":%.0f,\"removed_mm3\":%.3f}\n",
           moves, updates, secs, updates / secs, removed * res * res);
    return 0;
}
