/* test_design_office.c — the lighting-design demo (scenes/office/office.pbrt, 24 ceiling spots)
 * on its 0.75 m work-plane grid against an independent closed form: the direct illuminance
 * E = sum over the spots of I(theta) cos(incidence) / d^2, with pbrt-v4's spot falloff
 * I(theta) = I0 smoothstep(cos theta; cos 60, cos 40), at every grid point that no spot's ray
 * to it reaches through the pillar (the only obstacle above the work plane). */
#define PN_SCENE_FILES_PREFIX "pn_test_design_office"
#include "harness.h"
#include "scene_files.h"

#define OFFICE PN_SOURCE_DIR "/scenes/office/office.pbrt"

static double smoothstep(double x, double a, double b) {
    double t = (x - a) / (b - a);
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    return t * t * (3.0 - 2.0 * t);
}

/* Whether the segment p -> q passes through the pillar [5.8, 6.2] x [3.8, 4.2] x [0, 3]. */
static int hits_pillar(const double p[3], const double q[3]) {
    const double lo[3] = {5.8, 3.8, 0.0}, hi[3] = {6.2, 4.2, 3.0};
    double t0 = 0.0, t1 = 1.0;
    for (int k = 0; k < 3; k++) {
        double d = q[k] - p[k];
        if (fabs(d) < 1e-12) {
            if (p[k] < lo[k] || p[k] > hi[k]) return 0;
            continue;
        }
        double a = (lo[k] - p[k]) / d, b = (hi[k] - p[k]) / d;
        if (a > b) {
            double t = a;
            a = b;
            b = t;
        }
        t0 = fmax(t0, a);
        t1 = fmin(t1, b);
        if (t0 > t1) return 0;
    }
    return 1;
}

static void test_office_grid_closed_form(void) {
    pn_scene scene = NULL;
    if (pn_scene_load(test_context(), OFFICE, &scene) != PN_OK) {
        CHECK_MSG(0, "%s", pn_context_error_message(test_context()));
        return;
    }
    /* The grid of `penumbra illuminance --grid 0,0,12,8 --height 0.75 --spacing 0.5`. */
    enum { NU = 24, NV = 16 };
    static pn_illuminance_point pts[NU * NV];
    for (int j = 0; j < NV; j++)
        for (int i = 0; i < NU; i++) {
            pn_illuminance_point *p = &pts[j * NU + i];
            p->p[0] = (float)(0.25 + 0.5 * i);
            p->p[1] = (float)(0.25 + 0.5 * j);
            p->p[2] = 0.75f;
            p->n[0] = p->n[1] = 0.0f;
            p->n[2] = 1.0f;
        }
    static double lux[NU * NV];
    pn_render_settings s;
    memset(&s, 0, sizeof s);
    s.integrator = PN_INTEGRATOR_REFERENCE;
    s.spp = 16;
    s.threads = 2;
    CHECK(pn_illuminance(test_context(), scene, &s, pts, NU * NV, lux) == PN_OK);
    const double i0 = 2000.0, cos_end = cos(60.0 * M_PI / 180.0), cos_start = cos(40.0 * M_PI / 180.0);
    int compared = 0, excluded = 0;
    double worst = 0.0;
    for (int k = 0; k < NU * NV; k++) {
        const double q[3] = {pts[k].p[0], pts[k].p[1], pts[k].p[2]};
        double e = 0.0;
        int occluded = 0;
        for (int a = 0; a < 6; a++)
            for (int b = 0; b < 4; b++) {
                const double l[3] = {1.0 + 2.0 * a, 1.0 + 2.0 * b, 2.95};
                double d[3] = {q[0] - l[0], q[1] - l[1], q[2] - l[2]};
                double d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2], dist = sqrt(d2);
                double cos_axis = -d[2] / dist; /* the spots aim straight down */
                double intensity = i0 * smoothstep(cos_axis, cos_end, cos_start);
                if (intensity <= 0.0) continue;
                if (hits_pillar(l, q)) occluded = 1;
                e += intensity * cos_axis / d2; /* the plane's normal is +z: cos incidence = cos axis */
            }
        if (occluded) {
            excluded++;
            continue;
        }
        compared++;
        worst = fmax(worst, fabs(lux[k] / e - 1.0));
    }
    printf("  %d points compared, %d shaded by the pillar left out, worst relative difference %.3g\n", compared,
           excluded, worst);
    CHECK_MSG(worst < 0.005, "worst relative difference %g over %d points", worst, compared);
    CHECK(compared > 300 && excluded > 4);
    pn_scene_free(scene);
}

PN_TESTS(TEST(test_office_grid_closed_form))
