/* light_bvh.h — the light BVH of pbrt-v4 (Pharr, Jakob, Humphreys, "Physically Based Rendering",
 * 4th edition, §12.6.3, after Conty Estevez and Kulla, "Importance Sampling of Many Lights with
 * Adaptive Tree Splitting", 2018): lights are bounded by a box, a cone of emitting normals
 * (w, theta_o), an emission spread beyond it (theta_e) and their power phi; a binary tree built top
 * down with the surface-area-orientation heuristic; a light is chosen for a receiving point by
 * descending the tree, taking each child with probability proportional to its importance (a
 * cheap estimate of what the node's lights can give the point). Distant and environment lights
 * are outside the tree and chosen uniformly with probability n_inf / (n_inf + 1), as pbrt does.
 *
 * penumbra uses it as a second light sampler for the reference integrator (`--light-sampler
 * bvh`), so that the IAS comparison can be made against the sampler pbrt-v4 renders with. The
 * power phi is the luminance of the emitted radiance or intensity (pbrt takes the largest RGB
 * component): it only scales the importance, so either choice is unbiased. */
#ifndef PN_LIGHTS_LIGHT_BVH_H
#define PN_LIGHTS_LIGHT_BVH_H

#include "lights/lights.h"

typedef struct pn_light_bvh_bounds {
    vec3 bmin, bmax; /* box of the emitting geometry */
    vec3 w;          /* principal emitting normal */
    float phi;       /* power */
    float cos_o;     /* cos theta_o: normals lie within theta_o of w (-1: any direction) */
    float cos_e;     /* cos theta_e: emission reaches theta_e beyond the normals */
    bool two_sided;  /* emits around -w as well */
} pn_light_bvh_bounds;

typedef struct pn_light_bvh_node {
    pn_light_bvh_bounds b;
    int second; /* interior: index of the second child (the first is this index + 1);
                         leaf: the light's index in pn_lights */
    int parent; /* -1 at the root */
    bool leaf;
} pn_light_bvh_node;
_Static_assert(sizeof(pn_light_bvh_node) == 64, "a light BVH node fills one cache line (light_bvh.c)");

typedef struct pn_light_bvh {
    pn_light_bvh_node *nodes; /* depth first; the root is node 0 */
    int node_count;
    int *node_of_light; /* leaf of each light, -1 for lights outside the tree */
    int *infinite;      /* distant and environment lights */
    int infinite_count;
    int light_count;
} pn_light_bvh;

/* The bounds of one light; false for lights outside the tree (distant, environment) and for
 * lights without power. */
bool pn_light_bounds_of(const pn_lights *lights, const pn_light *l, pn_light_bvh_bounds *out);

/* pbrt-v4's LightBounds::Importance at point p with normal n (n = 0: no cosine factor). */
float pn_light_bounds_importance(const pn_light_bvh_bounds *b, vec3 p, vec3 n);

pn_status pn_light_bvh_build(const pn_lights *lights, pn_light_bvh *out, pn_err *err);
void pn_light_bvh_free(pn_light_bvh *bvh);

/* Chooses a light for the point (p, n) with u in [0,1): its index, or -1 when no light can be
 * chosen (every importance is zero); *pmf is the probability of the choice. */
int pn_light_bvh_sample(const pn_light_bvh *bvh, vec3 p, vec3 n, float u, float *pmf);

/* The stochastic descent of pn_light_bvh_sample from `node` down: u in [0,1) picks a child by
 * importance at every level and is rescaled within it; *pmf = prob times the product of the
 * choices' probabilities (0 and -1 when no leaf below can be chosen). */
int pn_light_bvh_descend(const pn_light_bvh *bvh, int node, vec3 p, vec3 n, double u, double prob, double *pmf);

/* A cut of the tree for the point (p, n) of at most max_nodes nodes. Every node carries the
 * probability that the stochastic descent from the root (pn_light_bvh_descend) passes through it: the root 1, a
 * child its parent's times its share of the two children's importance. Starting at the root, the
 * interior node of largest probability is replaced by its children with non-zero importance
 * until the next split would exceed max_nodes or only leaves are left (an importance-driven cut
 * in the spirit of Conty Estevez and Kulla 2018, without their variance bound). Writes the nodes
 * and their probabilities (which sum to 1 unless the cut is empty); returns their number.
 * *visited (if not NULL) counts the importance evaluations: at most 2 max_nodes - 1, whatever the
 * number of lights. With pn_light_bvh_descend from a cut node (two evaluations per level) the
 * cost per point is O(max_nodes + depth). */
int pn_light_bvh_cut(const pn_light_bvh *bvh, vec3 p, vec3 n, int max_nodes, int *nodes, float *prob, int *visited);

/* The probability that pn_light_bvh_sample chooses `light` at (p, n). */
float pn_light_bvh_pmf(const pn_light_bvh *bvh, vec3 p, vec3 n, int light);

#endif
