/* metals.c — lookup of the conductors' tables (metals.h). */
#include "spectral/metals.h"

#include "spectral/transport.h"

#include <string.h>

const pn_metal_table *pn_metal_table_named(const char *name) {
    for (int i = 0; i < PN_METAL_TABLE_COUNT; i++)
        if (strcmp(pn_metal_tables[i].name, name) == 0) return &pn_metal_tables[i];
    return NULL;
}

double pn_metal_eval(const pn_metal_table *t, double lambda) {
    return pn_table_eval(t->lambda, t->value, PN_METAL_SAMPLES, lambda);
}
