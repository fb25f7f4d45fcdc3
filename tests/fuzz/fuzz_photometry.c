/* fuzz_photometry.c — fuzz target of the measured-luminaire reader (IES LM-63, EULUMDAT): the
 * first byte chooses the format (even: IES, odd: EULUMDAT), the rest is the file. Any bytes must
 * give a table or an error status; a table is then evaluated in a spread of directions and at
 * tilt angles, so its interpolation is exercised on what the parser accepted. */
#include "fuzz_common.h"

#include "scene/photometry.h"

#include <math.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    if (size < 1) return 0;
    pn_photometry *p = NULL;
    pn_err err;
    pn_err_init(&err);
    if (pn_photometry_parse((const char *)data + 1, size - 1, "lamp", (data[0] & 1) != 0, &p, &err) == PN_OK && p) {
        volatile double sink = 0.0;
        for (int i = 0; i < 64; i++) {
            /* Fibonacci-sphere directions: every part of the sphere, every symmetry fold. */
            float z = 1.0f - (2.0f * (float)i + 1.0f) / 64.0f, r = sqrtf(fmaxf(0.0f, 1.0f - z * z));
            float phi = 2.39996323f * (float)i;
            sink += pn_photometry_eval(p, v3(r * cosf(phi), r * sinf(phi), z));
        }
        sink +=
            pn_photometry_tilt_factor(p, 0.0) + pn_photometry_tilt_factor(p, 45.0) + pn_photometry_tilt_factor(p, 95.0);
        (void)sink;
        pn_photometry_free(p);
    }
    return 0;
}
