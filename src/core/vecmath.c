/* vecmath.c — 4x4 transform construction and inversion (the pbrt-v4 conventions). */
#include "core/vecmath.h"

#include <string.h>

mat4 mat4_identity(void) {
    mat4 r;
    memset(&r, 0, sizeof r);
    for (int i = 0; i < 4; i++) r.m[i][i] = 1.0;
    return r;
}

mat4 mat4_mul(mat4 a, mat4 b) {
    mat4 r;
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) {
            double s = 0.0;
            for (int k = 0; k < 4; k++) s += a.m[i][k] * b.m[k][j];
            r.m[i][j] = s;
        }
    return r;
}

mat4 mat4_transpose(mat4 a) {
    mat4 r;
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) r.m[i][j] = a.m[j][i];
    return r;
}

bool mat4_is_finite(mat4 a) {
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++)
            if (!isfinite(a.m[i][j])) return false;
    return true;
}

/* Gauss-Jordan elimination with partial pivoting. */
bool mat4_inverse(mat4 a, mat4 *out) {
    if (!mat4_is_finite(a)) return false;
    double aug[4][8];
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) {
            aug[i][j] = a.m[i][j];
            aug[i][j + 4] = (i == j) ? 1.0 : 0.0;
        }
    for (int col = 0; col < 4; col++) {
        int pivot = col;
        for (int r = col + 1; r < 4; r++)
            if (fabs(aug[r][col]) > fabs(aug[pivot][col])) pivot = r;
        if (fabs(aug[pivot][col]) < 1e-300) return false;
        if (pivot != col)
            for (int j = 0; j < 8; j++) {
                double t = aug[col][j];
                aug[col][j] = aug[pivot][j];
                aug[pivot][j] = t;
            }
        double inv = 1.0 / aug[col][col];
        for (int j = 0; j < 8; j++) aug[col][j] *= inv;
        for (int r = 0; r < 4; r++) {
            if (r == col) continue;
            double f = aug[r][col];
            if (f == 0.0) continue;
            for (int j = 0; j < 8; j++) aug[r][j] -= f * aug[col][j];
        }
    }
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) out->m[i][j] = aug[i][j + 4];
    return mat4_is_finite(*out);
}

mat4 mat4_translate(double x, double y, double z) {
    mat4 r = mat4_identity();
    r.m[0][3] = x;
    r.m[1][3] = y;
    r.m[2][3] = z;
    return r;
}

mat4 mat4_scale(double x, double y, double z) {
    mat4 r = mat4_identity();
    r.m[0][0] = x;
    r.m[1][1] = y;
    r.m[2][2] = z;
    return r;
}

mat4 mat4_rotate(double angle_deg, double ax, double ay, double az) {
    double len = sqrt(ax * ax + ay * ay + az * az);
    mat4 r = mat4_identity();
    if (len == 0.0) return r;
    ax /= len;
    ay /= len;
    az /= len;
    double th = angle_deg * (3.14159265358979323846 / 180.0);
    double s = sin(th), c = cos(th);
    r.m[0][0] = ax * ax + (1 - ax * ax) * c;
    r.m[0][1] = ax * ay * (1 - c) - az * s;
    r.m[0][2] = ax * az * (1 - c) + ay * s;
    r.m[1][0] = ax * ay * (1 - c) + az * s;
    r.m[1][1] = ay * ay + (1 - ay * ay) * c;
    r.m[1][2] = ay * az * (1 - c) - ax * s;
    r.m[2][0] = ax * az * (1 - c) - ay * s;
    r.m[2][1] = ay * az * (1 - c) + ax * s;
    r.m[2][2] = az * az + (1 - az * az) * c;
    return r;
}

bool mat4_look_at(double ex, double ey, double ez, double lx, double ly, double lz, double ux, double uy, double uz,
                  mat4 *out) {
    double dx = lx - ex, dy = ly - ey, dz = lz - ez;
    double dl = sqrt(dx * dx + dy * dy + dz * dz);
    double ul = sqrt(ux * ux + uy * uy + uz * uz);
    if (!(dl > 0.0) || !(ul > 0.0)) return false;
    dx /= dl;
    dy /= dl;
    dz /= dl;
    ux /= ul;
    uy /= ul;
    uz /= ul;
    /* right = normalize(cross(up, dir)) — pbrt's left-handed convention */
    double rx = uy * dz - uz * dy, ry = uz * dx - ux * dz, rz = ux * dy - uy * dx;
    double rl = sqrt(rx * rx + ry * ry + rz * rz);
    if (!(rl > 1e-12)) return false;
    rx /= rl;
    ry /= rl;
    rz /= rl;
    double nx = dy * rz - dz * ry, ny = dz * rx - dx * rz, nz = dx * ry - dy * rx;
    mat4 world_from_camera = mat4_identity();
    world_from_camera.m[0][0] = rx;
    world_from_camera.m[1][0] = ry;
    world_from_camera.m[2][0] = rz;
    world_from_camera.m[0][1] = nx;
    world_from_camera.m[1][1] = ny;
    world_from_camera.m[2][1] = nz;
    world_from_camera.m[0][2] = dx;
    world_from_camera.m[1][2] = dy;
    world_from_camera.m[2][2] = dz;
    world_from_camera.m[0][3] = ex;
    world_from_camera.m[1][3] = ey;
    world_from_camera.m[2][3] = ez;
    return mat4_inverse(world_from_camera, out);
}

vec3 mat4_apply_point(const mat4 *m, vec3 p) {
    const double px = (double)p.x, py = (double)p.y, pz = (double)p.z;
    double x = m->m[0][0] * px + m->m[0][1] * py + m->m[0][2] * pz + m->m[0][3];
    double y = m->m[1][0] * px + m->m[1][1] * py + m->m[1][2] * pz + m->m[1][3];
    double z = m->m[2][0] * px + m->m[2][1] * py + m->m[2][2] * pz + m->m[2][3];
    double w = m->m[3][0] * px + m->m[3][1] * py + m->m[3][2] * pz + m->m[3][3];
    if (w != 1.0 && w != 0.0) {
        x /= w;
        y /= w;
        z /= w;
    }
    return v3((float)x, (float)y, (float)z);
}

vec3 mat4_apply_vector(const mat4 *m, vec3 v) {
    const double vx = (double)v.x, vy = (double)v.y, vz = (double)v.z;
    return v3((float)(m->m[0][0] * vx + m->m[0][1] * vy + m->m[0][2] * vz),
              (float)(m->m[1][0] * vx + m->m[1][1] * vy + m->m[1][2] * vz),
              (float)(m->m[2][0] * vx + m->m[2][1] * vy + m->m[2][2] * vz));
}

vec3 mat4_apply_normal(const mat4 *inv, vec3 n) {
    const double nx = (double)n.x, ny = (double)n.y, nz = (double)n.z;
    return v3((float)(inv->m[0][0] * nx + inv->m[1][0] * ny + inv->m[2][0] * nz),
              (float)(inv->m[0][1] * nx + inv->m[1][1] * ny + inv->m[2][1] * nz),
              (float)(inv->m[0][2] * nx + inv->m[1][2] * ny + inv->m[2][2] * nz));
}

double mat4_det3(const mat4 *m) {
    const double(*a)[4] = m->m;
    return a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
           a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
}
