/* light_tree.h — the Lightcuts light tree over a VPL set (Walter et al. 2005, §4 "Light tree"):
 * binary, built bottom-up by agglomerative clustering with the Lightcuts similarity metric
 *   I_C · (alpha_C^2 + c^2 (1 - cos beta_C)^2)
 * (alpha: diagonal of the cluster's bounding box; beta: half-angle of its cone of normals; c: the
 * scene's diagonal for oriented VPLs, 0 otherwise), one tree per VPL kind (omni, oriented,
 * directional; a directional cluster's box bounds its unit directions). Each node keeps its box,
 * cone, summed intensity and a representative VPL chosen at random in proportion to intensity
 * (luminance): merging children A and B, the representative is A's with probability
 * I_A / (I_A + I_B), so every VPL below a node is its representative with probability
 * I_vpl / I_node — the estimator of eq. 3 is unbiased in the Monte Carlo sense.
 *
 * Why this tree is separate from lights/cluster_tree.h (the ias light hierarchy): those nodes
 * index scene lights (area lights with extents, six oriented trees by cardinal direction, power
 * in lumens) and are built by a quadratic greedy pairing meant for about a thousand lights; the
 * VPL tree has a million point emitters, three trees, per-channel intensities and random
 * representatives, and needs a sub-quadratic build. What the cuts need from a node (box, cone,
 * intensity, children) has the same meaning in both, so a cut written against one can be moved
 * to the other; sharing one node type would have cost the ias nodes the representative and
 * RGB intensity fields and the VPL nodes ias's light ranges and sphere fields.
 *
 * Departure from Lightcuts' exact greedy agglomeration (which merges the globally best pair each
 * step, with a kd-tree for the nearest-neighbour queries, Walter et al. 2008): here each round
 * sorts the clusters in Morton order and every cluster looks for its best partner among its
 * PN_LIGHT_TREE_WINDOW neighbours on each side of that order; mutually-best pairs are merged,
 * and rounds repeat until one cluster remains (a locally-ordered agglomerative clustering). It
 * uses the same metric at O(n log n) cost; trees differ slightly from the exact greedy ones.
 *
 * Layout: the nodes are stored in depth-first pre-order, one tree after the other (a node's left
 * child is the next node; every subtree is a contiguous range). */
#ifndef PN_LIGHTS_LIGHT_TREE_H
#define PN_LIGHTS_LIGHT_TREE_H

#include "core/error.h"
#include "lights/vpl.h"
#include "shade/bounds.h"

#define PN_LIGHT_TREE_WINDOW 8

typedef struct pn_light_node {
    vec3 lo, hi;              /* box of positions (directional: of unit directions) */
    vec3 axis;                /* oriented: cone of emitting normals */
    float half;               /* its half-angle in radians (0 for omni and directional) */
    vec3 intensity;           /* summed RGB intensity */
    float weight;             /* luminance of intensity */
    int32_t left, right;      /* children, -1 for a leaf */
    int32_t rep;              /* representative VPL (index into the set) */
    int32_t count;            /* VPLs below */
    float cos_half, sin_half; /* of half */
} pn_light_node;

typedef struct pn_light_tree {
    pn_light_node *nodes;
    int32_t node_count;
    int32_t roots[PN_VPL_KIND_COUNT]; /* -1 where a kind has no VPL */
    float scene_diagonal;
    double seconds; /* build time */
} pn_light_tree;

pn_status pn_light_tree_build(const pn_vpl_set *set, float scene_diagonal, uint64_t seed, pn_light_tree *out,
                              pn_err *err);
void pn_light_tree_free(pn_light_tree *tree);

/* Reorders the VPL set as the tree's leaves (depth-first) and renumbers the representatives, so
 * that the representatives of nearby nodes are nearby in memory: a descent that shades
 * representatives (a cut, Phase I and II of illumcut) otherwise reads each VPL from a random place
 * of the set. The tree and the set keep the same VPLs and representatives. Time added to
 * tree->seconds. */
pn_status pn_light_tree_order_vpls(pn_light_tree *tree, pn_vpl_set *set, pn_err *err);

/* The Lightcuts metric of a node with this box, cone and intensity. */
float pn_light_tree_metric(int kind, vec3 lo, vec3 hi, float half, float weight, float scene_diagonal);

/* The bounds record of a node (kind of its tree). */
static inline pn_light_bounds pn_light_node_bounds(const pn_light_node *n, int kind) {
    pn_light_bounds b = {kind, n->lo, n->hi, n->axis, n->half, n->cos_half, n->sin_half};
    return b;
}

/* Radius of the ball around the node's box (directional: of its direction box). */
static inline float pn_light_node_radius(const pn_light_node *n) {
    return 0.5f * v3_length(v3_sub(n->hi, n->lo));
}

#endif
