/* vecmath.h — small inline vector and frame math used everywhere (float vectors, double 4x4). */
#ifndef PN_CORE_VECMATH_H
#define PN_CORE_VECMATH_H

#include <math.h>
#include <stdbool.h>

#define PN_PI 3.14159265358979323846f
#define PN_INV_PI 0.31830988618379067154f
#define PN_INV_4PI 0.07957747154594766788f

typedef struct vec3 {
    float x, y, z;
} vec3;

typedef struct vec2 {
    float x, y;
} vec2;

static inline vec3 v3(float x, float y, float z) {
    return (vec3){x, y, z};
}
static inline vec3 v3_add(vec3 a, vec3 b) {
    return v3(a.x + b.x, a.y + b.y, a.z + b.z);
}
static inline vec3 v3_sub(vec3 a, vec3 b) {
    return v3(a.x - b.x, a.y - b.y, a.z - b.z);
}
static inline vec3 v3_mul(vec3 a, vec3 b) {
    return v3(a.x * b.x, a.y * b.y, a.z * b.z);
}
static inline vec3 v3_scale(vec3 a, float s) {
    return v3(a.x * s, a.y * s, a.z * s);
}
static inline vec3 v3_madd(vec3 a, vec3 b, float s) {
    return v3(a.x + b.x * s, a.y + b.y * s, a.z + b.z * s);
}
static inline vec3 v3_neg(vec3 a) {
    return v3(-a.x, -a.y, -a.z);
}
static inline float v3_dot(vec3 a, vec3 b) {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}
static inline vec3 v3_cross(vec3 a, vec3 b) {
    return v3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
static inline float v3_length2(vec3 a) {
    return v3_dot(a, a);
}
static inline float v3_length(vec3 a) {
    return sqrtf(v3_dot(a, a));
}
static inline vec3 v3_normalize(vec3 a) {
    float l = v3_length(a);
    return l > 0.0f ? v3_scale(a, 1.0f / l) : a;
}
static inline vec3 v3_min(vec3 a, vec3 b) {
    return v3(fminf(a.x, b.x), fminf(a.y, b.y), fminf(a.z, b.z));
}
static inline vec3 v3_max(vec3 a, vec3 b) {
    return v3(fmaxf(a.x, b.x), fmaxf(a.y, b.y), fmaxf(a.z, b.z));
}
static inline float v3_max_component(vec3 a) {
    return fmaxf(a.x, fmaxf(a.y, a.z));
}
static inline float v3_get(vec3 a, int i) {
    return i == 0 ? a.x : (i == 1 ? a.y : a.z);
}
static inline bool v3_is_finite(vec3 a) {
    return isfinite(a.x) && isfinite(a.y) && isfinite(a.z);
}
static inline bool v3_is_zero(vec3 a) {
    return a.x == 0.0f && a.y == 0.0f && a.z == 0.0f;
}
/* Rec. 709 / sRGB luminance of linear RGB. */
static inline float v3_luminance(vec3 c) {
    return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z;
}

/* An orthonormal basis around n (Duff et al. 2017, "Building an Orthonormal Basis, Revisited"). */
/* cos and sin of max(0, a - b) from the cosines and sines of angles a and b in [0, pi] (the
 * bounding-cone arithmetic of pbrt-v4's light bounds). */
static inline float pn_cos_sub_clamped(float sin_a, float cos_a, float sin_b, float cos_b) {
    return cos_a > cos_b ? 1.0f : cos_a * cos_b + sin_a * sin_b;
}

static inline float pn_sin_sub_clamped(float sin_a, float cos_a, float sin_b, float cos_b) {
    return cos_a > cos_b ? 0.0f : sin_a * cos_b - cos_a * sin_b;
}

static inline void v3_basis(vec3 n, vec3 *t, vec3 *b) {
    float sign = copysignf(1.0f, n.z);
    float a = -1.0f / (sign + n.z);
    float bb = n.x * n.y * a;
    *t = v3(1.0f + sign * n.x * n.x * a, sign * bb, -sign * n.x);
    *b = v3(bb, sign + n.y * n.y * a, -n.y);
}

/* Row-major 4x4 double matrix: m[r][c]; points are column vectors (p' = M p). */
typedef struct mat4 {
    double m[4][4];
} mat4;

mat4 mat4_identity(void);
mat4 mat4_mul(mat4 a, mat4 b);
/* Returns false if the matrix is singular (or not finite). */
bool mat4_inverse(mat4 a, mat4 *out);
mat4 mat4_transpose(mat4 a);
bool mat4_is_finite(mat4 a);
mat4 mat4_translate(double x, double y, double z);
mat4 mat4_scale(double x, double y, double z);
mat4 mat4_rotate(double angle_deg, double ax, double ay, double az);
/* pbrt's LookAt: returns camera-from-world; false if degenerate (up parallel to view). */
bool mat4_look_at(double ex, double ey, double ez, double lx, double ly, double lz, double ux, double uy, double uz,
                  mat4 *out);
vec3 mat4_apply_point(const mat4 *m, vec3 p);
vec3 mat4_apply_vector(const mat4 *m, vec3 v);
/* Normals transform by the inverse transpose; pass the inverse matrix. */
vec3 mat4_apply_normal(const mat4 *inverse, vec3 n);
/* Determinant of the upper 3x3 (negative when the transform swaps handedness). */
double mat4_det3(const mat4 *m);

#endif
