/* noise_floor.c — how much of a progressive image's error against the full render no
 * reconstruction can remove (issue 18). Reads REF0 (the full render, the comparison's reference),
 * REF1 (the same full render with another --seed), IMAGE (the progressive image) and optionally
 * an EXR with IMAGE's sampling_pattern and block_map AOVs. Prints IMAGE's rel L1 / L2 against
 * REF0; one render's own noise, |REF1 - REF0| / sqrt 2; the floor of a reconstruction that hits
 * the expectation at every unevaluated work pixel, that noise times sqrt(1 - f) per output pixel
 * (f: the evaluated share of its work pixels); and with block_map the split by block class (0
 * smooth, 3 edge block under boundary evaluation). Also IMAGE against REF1 (whose noise is independent of
 * IMAGE's), and from it IMAGE's L2 against the expectation (a converged render). Built as build/pn_noise_floor (public API only).
 * usage: pn_noise_floor REF0.exr REF1.exr IMAGE.exr [IMAGE_WITH_AOVS.exr] */
#include <penumbra/penumbra.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
static pn_image rd(pn_context c, const char *p, int layers) {
    pn_image im = NULL;
    if ((layers ? pn_image_read_layers(c, p, &im) : pn_image_read(c, p, &im)) != PN_OK) {
        fprintf(stderr, "read %s failed\n", p);
        return NULL;
    }
    return im;
}
static const float *layer(pn_image im, const char *name) {
    for (int l = 0; l < pn_image_layer_count(im); l++)
        if (!strcmp(pn_image_layer_name(im, l), name)) return pn_image_layer_data(im, l);
    return NULL;
}
int main(int argc, char **argv) {
    if (argc < 4) return 2;
    pn_context c = pn_context_new();
    pn_image r0 = rd(c, argv[1], 0), r1 = rd(c, argv[2], 0), im = rd(c, argv[3], 0);
    pn_image aov = argc > 4 ? rd(c, argv[4], 1) : NULL;
    if (!r0 || !r1 || !im) return 1;
    int n = pn_image_width(r0) * pn_image_height(r0);
    const float *a = pn_image_layer_data(r0, 0), *b = pn_image_layer_data(r1, 0), *x = pn_image_layer_data(im, 0);
    const float *pat = aov ? layer(aov, "sampling_pattern") : NULL, *map = aov ? layer(aov, "block_map") : NULL;
    double s1 = 0, s2 = 0, e1 = 0, e2 = 0, n1 = 0, n2 = 0, f1 = 0, f2 = 0, g1 = 0, g2 = 0;
    double ce2[8] = {0}, cn2[8] = {0}, ce1[8] = {0}, cf1[8] = {0}, cnt[8] = {0};
    for (int i = 0; i < n; i++) {
        double f = pat ? (double)pat[i] : 0.0, u = 1.0 - f;
        int k = map ? (int)map[i] & 7 : 0;
        for (int ch = 0; ch < 3; ch++) {
            double r = a[3 * i + ch], d = (double)x[3 * i + ch] - r, nd = ((double)b[3 * i + ch] - r) / sqrt(2.0);
            s1 += fabs(r);
            s2 += r * r;
            e1 += fabs(d);
            e2 += d * d;
            double g = (double)x[3 * i + ch] - (double)b[3 * i + ch]; /* against REF1, independent of IMAGE */
            g1 += fabs(g);
            g2 += g * g;
            n1 += fabs(nd);
            n2 += nd * nd;
            f1 += sqrt(u) * fabs(nd);
            f2 += u * nd * nd;
            ce2[k] += d * d;
            cn2[k] += u * nd * nd;
            ce1[k] += fabs(d);
            cf1[k] += sqrt(u) * fabs(nd);
        }
        cnt[k] += 1;
    }
    printf("image vs ref0: relL1 %.4f relL2 %.4f\n", e1 / s1, sqrt(e2 / s2));
    printf("image vs ref1: relL1 %.4f relL2 %.4f\n", g1 / s1, sqrt(g2 / s2));
    /* REF1's noise is independent of IMAGE, so |IMAGE - REF1|^2 = |IMAGE - E|^2 + |REF1 - E|^2 on
     * average: IMAGE's L2 against the expectation E (a converged render) is estimated exactly. */
    printf("image vs expectation (|x-ref1|^2 - noise^2): relL2 %.4f\n", sqrt(fmax(0.0, g2 - n2) / s2));
    printf("one render's noise (|ref1-ref0|/sqrt2): relL1 %.4f relL2 %.4f\n", n1 / s1, sqrt(n2 / s2));
    if (pat)
        printf("floor at this pattern (expectation at unevaluated work pixels): relL1 %.4f relL2 %.4f\n", f1 / s1,
               sqrt(f2 / s2));
    if (map)
        for (int k = 0; k < 8; k++)
            if (cnt[k] > 0)
                printf("  class %d: %5.1f%% pixels, L1 %.4f (floor %.4f), L2^2 share %.2f (floor part %.2f)\n", k,
                       100 * cnt[k] / n, ce1[k] / s1, cf1[k] / s1, ce2[k] / e2, cn2[k] / e2);
    return 0;
}
