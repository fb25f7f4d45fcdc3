/* cluster_tree.h — light cluster hierarchies (Donikian et al. 2006, "Iterative Adaptive Sampling
 * for Accurate Direct Illumination", §4.3 "Light Clusters", §4.3.1 "Constructing the Cluster
 * Tree", §5.7 "Clustering").
 *
 * One binary tree for omnidirectional lights and six for oriented lights (by the dominant
 * cardinal direction of their emitting normal / spot axis), each built greedily bottom-up by
 * always merging the pair of clusters whose merged bounding sphere is smallest. A per-point cut
 * walks down the trees to clusters that subtend less than a solid angle (or to leaves), after
 * removing subtrees that cannot light the point (below its horizon, facing away).
 *
 * The node records carry what other cuts need too (bounding sphere and box, normal cone with an
 * emission spread, power, a contiguous light range), so error-bounded cuts (lightcuts, illumcut)
 * can walk the same trees.
 */
#ifndef PN_LIGHTS_CLUSTER_TREE_H
#define PN_LIGHTS_CLUSTER_TREE_H

#include "core/error.h"
#include "core/vecmath.h"
#include "lights/lights.h"

#include <stdbool.h>
#include <stddef.h>

typedef struct pn_cluster_node {
    int left, right; /* children, -1 for a leaf */
    int parent;      /* -1 for a root (and for a single's node) */
    int light;       /* leaf: index into pn_lights.lights; interior: -1 */
    vec3 center;
    float radius;     /* bounding sphere of all the lights' geometry below (area lights:
                                  their extent); singles: center = direction towards the light,
                                  radius 0 */
    float power;      /* sum of the lights' luminous power (pn_cluster_light_power) */
    int first, count; /* the node's lights are light_order[first .. first+count) */
    vec3 axis;
    float cos_spread;       /* oriented trees: a cone bounding the emitting normals (axis,
                                    cos of half-angle); omni: axis 0, cos_spread -1 */
    float cos_emit;         /* cos of the widest emission half-angle around any of those
                                  normals: 0 for one-sided planar lights (a hemisphere),
                                  cos_total_width for spots, -1 in the omni tree */
    vec3 bmin, bmax;        /* axis-aligned box of the lights' geometry below */
    int tree;               /* pn_tree_kind of the node's tree, or -1 for a single */
    float cone_angle;       /* acos(cos_spread) + acos(cos_emit) */
    float cut_cos, cut_sin; /* cos and sin of cone_angle plus a safety margin, for the cut's
                                  facing-away test without inverse trigonometry; cut_cos = -2
                                  when that angle reaches pi (the test can never cull) */
} pn_cluster_node;

typedef enum pn_tree_kind {
    PN_TREE_OMNI = 0,
    PN_TREE_POS_X,
    PN_TREE_NEG_X,
    PN_TREE_POS_Y,
    PN_TREE_NEG_Y,
    PN_TREE_POS_Z,
    PN_TREE_NEG_Z,
    PN_TREE_COUNT
} pn_tree_kind;

/* pn_cluster_light_tree's answers besides a pn_tree_kind. */
#define PN_CLUSTER_SINGLE (-1)   /* distant lights: their own one-light node, never merged */
#define PN_CLUSTER_EXCLUDED (-2) /* environment lights: handled by env-map regions */

typedef struct pn_cluster_forest {
    pn_cluster_node *nodes;
    int node_count;
    int roots[PN_TREE_COUNT]; /* -1 where a tree is empty */
    int *light_order;         /* lights in leaf order (each subtree contiguous); the trees'
                                  lights first, then the singles' lights */
    int order_count;          /* entries of light_order */
    int *leaf_of_light;       /* node index of each light's leaf (singles included: their
                                  one-light node), -1 for environment lights */
    int *singles;
    int single_count;     /* node indices of the distant lights' one-light nodes: never
                                       clustered, always their own cluster */
    double *power_prefix; /* order_count + 1 running sums of the lights' power in
                                  light_order, for pn_cluster_pick */
    double *power_coarse; /* every PN_CLUSTER_COARSE-th of them, power_prefix[(j + 1) * PN_CLUSTER_COARSE]
                                  (clamped at order_count): pn_cluster_pick searches these first, so
                                  that a pick reads a few cache lines of power_prefix, not log2(count) */
    int coarse_count;
    int *ranges;     /* node_count pairs: each node's first and count again, compact (8 bytes
                                  where the node is 140), for pn_cluster_pick */
    int light_count; /* pn_lights.count at build time */
} pn_cluster_forest;

#define PN_CLUSTER_COARSE 16

/* Builds the seven trees and the singles. On failure *out is left zeroed. */
pn_status pn_cluster_forest_build(const pn_lights *lights, pn_cluster_forest *out, pn_err *err);
void pn_cluster_forest_free(pn_cluster_forest *f);

/* The cut for a shading point p with unit normal n (n = (0,0,0) disables the horizon test, e.g.
 * for transmissive surfaces). Each tree is walked down from its root:
 *   - a node whose lights cannot light p is skipped with its subtree ("culled"): interior nodes
 *     conservatively (bounding sphere below p's tangent plane; normal cone + emission spread +
 *     bounding sphere all facing away), leaves exactly (pn_cluster_light_culled);
 *   - otherwise a node is taken when pn_cluster_solid_angle(center, radius, p) < max_solid_angle,
 *     or when it is a leaf; else both children are visited.
 * Then each single (distant light) is taken when it is above p's horizon, else culled.
 * Output encoding: out[] holds node indices into f->nodes, nothing else — singles are nodes too
 * (f->nodes[i].tree == -1). The first `capacity` node indices are written to out[] and the total
 * count is returned (more than capacity: call again with a larger buffer). */
int pn_cluster_cut(const pn_cluster_forest *f, const pn_lights *lights, vec3 p, vec3 n, float max_solid_angle, int *out,
                   int capacity);

/* pn_cluster_cut that also reports the culled nodes (whose lights give p nothing): the first
 * culled_capacity of them go to culled[] (may be NULL with capacity 0), their total count to
 * *culled_count (may be NULL). The taken and culled nodes' light ranges partition all the lights
 * of the forest. */
int pn_cluster_cut_ex(const pn_cluster_forest *f, const pn_lights *lights, vec3 p, vec3 n, float max_solid_angle,
                      int *out, int capacity, int *culled, int culled_capacity, int *culled_count);

/* pn_cluster_cut with at most max_count clusters (issue 15: a cut whose size stops growing with
 * the number of lights). When the plain cut has at most max_count clusters it is the answer, the
 * same clusters in the same order. Otherwise the trees are refined from their roots by priority,
 * the open node of largest solid angle first, each refined node replaced by its children that are
 * not culled, while the count (taken, open and the singles not culled) stays within max_count: a
 * node whose refinement would pass it is taken whole, although it subtends max_solid_angle or
 * more (refined after all if a later refinement culls both children and so makes room). The
 * result then has max_count clusters (unless the roots and singles alone are more), in the
 * depth-first walk's order. `work` holds pn_cluster_cut_capped_work(max_count) bytes. max_count
 * <= 0: no cap. When the count returned is above capacity, out[] holds only some of them. */
int pn_cluster_cut_capped(const pn_cluster_forest *f, const pn_lights *lights, vec3 p, vec3 n, float max_solid_angle,
                          int max_count, int *out, int capacity, void *work);
size_t pn_cluster_cut_capped_work(int max_count);

/* Cuts shared between nearby points (stop 21: an ias pixel's antialiasing regions on one surface
 * are a fraction of a pixel apart, and most of their cuts' decisions are the same). A record walk
 * computes the cut at p (as pn_cluster_cut) and notes every node whose decision would be the same
 * for every point p' within `delta` of p with a normal n' within `dn` of n (|n' - n|, n' not
 * zero), with room for the rounding; a replay walk for such a p', n' reads the noted decisions
 * and classifies the others itself: the same cut as pn_cluster_cut at p', bit for bit. When the
 * record decided every node it met (all_sure) the replay's cut is the record's. Stamps tell the
 * records apart. No cap (pn_cluster_cut_capped's
 * max_count) and no culled list. */
typedef struct pn_cluster_cut_link {
    int left, skip; /* the walk's next node: descending, or past the node's subtree (-1: the tree's end) */
    uint32_t memo;  /* stamp << 2 | the node's decision in the record of that stamp */
} pn_cluster_cut_link;

typedef struct pn_cluster_cut_share {
    pn_cluster_cut_link *links; /* per node, 12 bytes where the node is 140: what a replay reads */
    int node_count;
    uint32_t stamp; /* the current record's; 0: none */
    bool all_sure;  /* the current record decided every node it met for the whole ball */
    int met, sure;  /* the nodes the current record met, and those it decided for the whole ball */
} pn_cluster_cut_share;

bool pn_cluster_cut_share_init(pn_cluster_cut_share *sh, const pn_cluster_forest *f);
void pn_cluster_cut_share_free(pn_cluster_cut_share *sh);
int pn_cluster_cut_record(const pn_cluster_forest *f, const pn_lights *lights, vec3 p, vec3 n, float max_solid_angle,
                          float delta, float dn, int *out, int capacity, pn_cluster_cut_share *sh);
/* The caller guarantees |p - p_record| <= delta and |n - n_record| <= dn, n not zero. */
int pn_cluster_cut_replay(const pn_cluster_forest *f, const pn_lights *lights, vec3 p, vec3 n, float max_solid_angle,
                          int *out, int capacity, pn_cluster_cut_share *sh);

/* Chooses a light of node `node` in proportion to the lights' power (the paper: "based on their
 * relative intensities"); u in [0,1); returns the light index and its probability within the
 * node, power(light) / power(node) (uniform 1/count when the whole node has zero power). Binary
 * search over the node's contiguous range of power_prefix: O(log count). */
int pn_cluster_pick(const pn_cluster_forest *f, const pn_lights *lights, int node, float u, float *prob);

/* Probability that pn_cluster_pick(node) returns `light` (0 if the light is not below node). */
float pn_cluster_pick_pdf(const pn_cluster_forest *f, const pn_lights *lights, int node, int light);

/* Chooses a light of node `node` by importance at the point p (unit normal n; n = 0: no horizon):
 * from the node down, while the node is interior and subtends max_solid_angle or more from p
 * (always, max_solid_angle <= 0), each child is taken in proportion to pn_cluster_importance at p
 * (in proportion to power where both children have none, and to their light counts where both
 * have no power either), u rescaled to [0,1) within the chosen child for the next level; below,
 * pn_cluster_pick (by power) with the rescaled u. Returns the light and, in *prob, its
 * probability: the product of the choices along the path. O(depth of the descent) importance
 * evaluations. */
int pn_cluster_pick_importance(const pn_cluster_forest *f, const pn_lights *lights, int node, vec3 p, vec3 n,
                               float max_solid_angle, float u, float *prob);

/* Probability that pn_cluster_pick_importance(node, p, n, max_solid_angle) returns `light` (0 if the
 * light is not below node): the same products along the light's path from node. */
float pn_cluster_pick_importance_pdf(const pn_cluster_forest *f, const pn_lights *lights, int node, vec3 p, vec3 n,
                                     float max_solid_angle, int light);

/* A bound on node nd's unoccluded irradiance at p (unit normal n, or 0), up to a constant:
 * power x (a bound on the emitting cosine over the node's normal cone and bounding sphere) x (a
 * bound on the incident cosine over the sphere) / max(d^2, r^2), each cosine bound kept at least
 * 1e-3: never 0 for a node with power, so that no light that can light p is left out, whatever
 * the rounding (a node facing away or below the horizon keeps 1e-3 or 1e-6 of its weight). */
double pn_cluster_importance(const pn_cluster_node *nd, vec3 p, vec3 n);

/* ---- building blocks, shared with the tests and other cuts ---- */

/* Luminous power used for picking and node sums: point 4 pi I, spot 2 pi I (1 - (cos_start +
 * cos_width) / 2), goniometric 4 pi I, one-sided planar pi L A (two-sided twice), sphere
 * pi L 4 pi r^2; distant: the luminance of its irradiance (only ever alone in its node);
 * environment 0; projection: its exact power, pn_light.power. Luminances clamped at 0. */
float pn_cluster_light_power(const pn_light *l);

/* The tree a light belongs to (pn_tree_kind), PN_CLUSTER_SINGLE or PN_CLUSTER_EXCLUDED. */
int pn_cluster_light_tree(const pn_light *l);

/* Bounding sphere of a light's geometry: points radius 0, spheres themselves, triangles and
 * rectangles centroid + largest vertex distance, disks centre + radius. */
void pn_cluster_light_sphere(const pn_light *l, vec3 *center, float *radius);

/* The smallest sphere containing two spheres (radius rounded up so it really contains them);
 * its radius is the greedy construction's merge cost. */
void pn_cluster_merge_spheres(vec3 c1, float r1, vec3 c2, float r2, vec3 *center, float *radius);

/* Solid angle subtended from p by the sphere (center, radius): 2 pi (1 - sqrt(1 - r^2/d^2)),
 * 4 pi when p is inside (or on) the sphere. */
float pn_cluster_solid_angle(vec3 center, float radius, vec3 p);

/* Axis-aligned box of a light's emitting geometry (a point for point-like lights); shared with
 * the light BVH (light_bvh.c). */
void pn_cluster_light_box(const pn_light *l, vec3 *lo, vec3 *hi);

/* The smallest cone holding the cones (wa, cos ca) and (wb, cos cb), as pbrt-v4's DirectionCone
 * union, with its cosine rounded down so the cone never comes out too narrow; cos -1 is the whole
 * sphere. Shared with the light BVH. */
void pn_cluster_merge_cones(vec3 wa, float ca, vec3 wb, float cb, vec3 *w, float *c);

/* True when light l certainly gives nothing to a point p with unit normal n (n = 0: no horizon
 * test): its geometry lies on or below p's tangent plane, p is behind a one-sided planar light,
 * or outside a spot light's cone; distant lights below the horizon. Environment lights: false. */
bool pn_cluster_light_culled(const pn_light *l, vec3 p, vec3 n);

#endif
