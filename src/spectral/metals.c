/* metals.c — lookup of the conductors' tables (metals.h). */
#include "spectral/metals.h"

#include <string.h>

const pn_metal_table *pn_metal_table_named(const char *name) {
    for (int i = 0; i < PN_METAL_TABLE_COUNT; i++)
        if (strcmp(pn_metal_tables[i].name, name) == 0) return &pn_metal_tables[i];
    return NULL;
}

double pn_metal_eval(const pn_metal_table *t, double lambda) {
    const double *l = t->lambda, *v = t->value;
    if (!(lambda > l[0])) return v[0];
    if (lambda >= l[PN_METAL_SAMPLES - 1]) return v[PN_METAL_SAMPLES - 1];
    int lo = 0, hi = PN_METAL_SAMPLES - 1; /* l[lo] <= lambda < l[hi] */
    while (hi - lo > 1) {
        int mid = (lo + hi) / 2;
        if (l[mid] <= lambda)
            lo = mid;
        else
            hi = mid;
    }
    double u = (lambda - l[lo]) / (l[hi] - l[lo]);
    return v[lo] * (1.0 - u) + v[hi] * u;
}
