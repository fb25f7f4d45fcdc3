/* camera.c — perspective projection with pbrt-v4's conventions, thin lens, filter sampling. */
#include "driver/camera.h"

#include <string.h>

static float filter_eval(const pn_camera_def *def, float x, float radius) {
    float ax = fabsf(x);
    switch (def->filter) {
    case PN_FILTER_BOX: return ax <= radius ? 1.0f : 0.0f;
    case PN_FILTER_TRIANGLE: return fmaxf(0.0f, radius - ax);
    case PN_FILTER_GAUSSIAN: {
        float s = def->gaussian_sigma > 0.0f ? def->gaussian_sigma : 0.5f;
        float g = expf(-x * x / (2.0f * s * s)) - expf(-radius * radius / (2.0f * s * s));
        return fmaxf(0.0f, g);
    }
    case PN_FILTER_MITCHELL: {
        /* Mitchell–Netravali on [-2, 2] scaled to the radius. */
        float B = def->mitchell_b, C = def->mitchell_c;
        float t = 2.0f * ax / radius;
        if (t >= 2.0f) return 0.0f;
        if (t >= 1.0f)
            return ((-B - 6 * C) * t * t * t + (6 * B + 30 * C) * t * t + (-12 * B - 48 * C) * t +
                    (8 * B + 24 * C)) / 6.0f;
        return ((12 - 9 * B - 6 * C) * t * t * t + (-18 + 12 * B + 6 * C) * t * t + (6 - 2 * B)) / 6.0f;
    }
    }
    return 1.0f;
}

static void filter_axis_setup(const pn_camera_def *def, float radius, pn_filter_axis *ax) {
    if (!(radius > 0.0f)) radius = 0.5f;
    ax->radius = radius;
    float w = 2.0f * radius / PN_FILTER_TABLE;
    ax->cdf[0] = 0.0f;
    double acc = 0.0;
    for (int i = 0; i < PN_FILTER_TABLE; i++) {
        float x = -radius + ((float)i + 0.5f) * w;
        ax->f[i] = filter_eval(def, x, radius);
        acc += fabs((double)ax->f[i]) * (double)w;
        ax->cdf[i + 1] = (float)acc;
    }
    ax->integral_abs = (float)acc;
    if (acc > 0.0)
        for (int i = 1; i <= PN_FILTER_TABLE; i++) ax->cdf[i] = (float)((double)ax->cdf[i] / acc);
    ax->cdf[PN_FILTER_TABLE] = 1.0f;
}

/* Returns the offset in [-radius, radius] and the sign-carrying weight f / pdf scaled so that a
 * non-negative filter gives exactly 1 (pbrt-v4: the tabulated value over its density). */
static float filter_axis_sample(const pn_filter_axis *ax, float u, float *weight) {
    if (ax->integral_abs <= 0.0f) {
        *weight = 1.0f;
        return (u - 0.5f) * 2.0f * ax->radius;
    }
    int lo = 0, hi = PN_FILTER_TABLE;
    while (hi - lo > 1) {
        int mid = (lo + hi) / 2;
        if (ax->cdf[mid] <= u) lo = mid;
        else hi = mid;
    }
    float span = ax->cdf[lo + 1] - ax->cdf[lo];
    float t = span > 0.0f ? (u - ax->cdf[lo]) / span : 0.5f;
    float w = 2.0f * ax->radius / PN_FILTER_TABLE;
    *weight = ax->f[lo] >= 0.0f ? 1.0f : -1.0f;
    return -ax->radius + ((float)lo + t) * w;
}

bool pn_camera_setup(const pn_camera_def *def, int full_width, int full_height, const float crop[4],
                     pn_camera *cam) {
    memset(cam, 0, sizeof *cam);
    cam->world_from_camera = def->world_from_camera;
    float fov = def->fov_deg > 0.0f ? def->fov_deg : 90.0f;
    cam->tan_half_fov = tanf(0.5f * fov * PN_PI / 180.0f);
    cam->full_width = full_width;
    cam->full_height = full_height;
    float aspect = (float)full_width / (float)full_height;
    bool has_screen = def->screen_window[0] != def->screen_window[1] && def->screen_window[2] != def->screen_window[3];
    if (has_screen) {
        memcpy(cam->screen, def->screen_window, sizeof cam->screen);
    } else if (aspect > 1.0f) {
        cam->screen[0] = -aspect;
        cam->screen[1] = aspect;
        cam->screen[2] = -1.0f;
        cam->screen[3] = 1.0f;
    } else {
        cam->screen[0] = -1.0f;
        cam->screen[1] = 1.0f;
        cam->screen[2] = -1.0f / aspect;
        cam->screen[3] = 1.0f / aspect;
    }
    cam->lens_radius = def->lens_radius;
    cam->focal_distance = def->focal_distance > 0.0f ? def->focal_distance : 1e6f;
    cam->x0 = (int)ceilf((float)full_width * crop[0]);
    cam->x1 = (int)ceilf((float)full_width * crop[1]);
    cam->y0 = (int)ceilf((float)full_height * crop[2]);
    cam->y1 = (int)ceilf((float)full_height * crop[3]);
    if (cam->x0 < 0) cam->x0 = 0;
    if (cam->y0 < 0) cam->y0 = 0;
    if (cam->x1 > full_width) cam->x1 = full_width;
    if (cam->y1 > full_height) cam->y1 = full_height;
    float rx = def->filter_radius[0] > 0.0f ? def->filter_radius[0] : 0.5f;
    float ry = def->filter_radius[1] > 0.0f ? def->filter_radius[1] : 0.5f;
    filter_axis_setup(def, rx, &cam->filter_x);
    filter_axis_setup(def, ry, &cam->filter_y);
    return cam->x1 > cam->x0 && cam->y1 > cam->y0;
}

void pn_camera_filter_sample(const pn_camera *cam, int px, int py, float u1, float u2, float *rx,
                             float *ry, float *weight) {
    float wx, wy;
    float dx = filter_axis_sample(&cam->filter_x, u1, &wx);
    float dy = filter_axis_sample(&cam->filter_y, u2, &wy);
    *rx = (float)px + 0.5f + dx;
    *ry = (float)py + 0.5f + dy;
    *weight = wx * wy;
}

void pn_camera_ray(const pn_camera *cam, float rx, float ry, float l1, float l2, vec3 *origin, vec3 *dir) {
    /* Raster to screen: x grows right, raster y grows down while screen y grows up. */
    float sx = cam->screen[0] + (rx / (float)cam->full_width) * (cam->screen[1] - cam->screen[0]);
    float sy = cam->screen[3] - (ry / (float)cam->full_height) * (cam->screen[3] - cam->screen[2]);
    vec3 d = v3(sx * cam->tan_half_fov, sy * cam->tan_half_fov, 1.0f);
    vec3 o = v3(0, 0, 0);
    if (cam->lens_radius > 0.0f) {
        /* Thin lens: concentric disk sample on the lens, focus on the plane z = focal_distance. */
        float a = 2.0f * l1 - 1.0f, b = 2.0f * l2 - 1.0f;
        float r, th;
        if (a == 0.0f && b == 0.0f) {
            r = 0.0f;
            th = 0.0f;
        } else if (fabsf(a) > fabsf(b)) {
            r = a;
            th = (PN_PI / 4.0f) * (b / a);
        } else {
            r = b;
            th = PN_PI / 2.0f - (PN_PI / 4.0f) * (a / b);
        }
        vec3 lens = v3(cam->lens_radius * r * cosf(th), cam->lens_radius * r * sinf(th), 0.0f);
        vec3 focus = v3_scale(d, cam->focal_distance / d.z);
        o = lens;
        d = v3_sub(focus, lens);
    }
    *origin = mat4_apply_point(&cam->world_from_camera, o);
    *dir = v3_normalize(mat4_apply_vector(&cam->world_from_camera, d));
}
