/* camera.c — pbrt-v4's cameras (cameras.cpp: perspective and orthographic with a thin lens,
 * spherical with its two mappings), filter sampling, and the film's response (film.cpp:
 * PixelSensor's imaging ratio and white balance, RGBFilm's maxcomponentvalue). */
#include "render/camera.h"

#include "lights/lights.h"

#include <math.h>
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
            return ((-B - 6 * C) * t * t * t + (6 * B + 30 * C) * t * t + (-12 * B - 48 * C) * t + (8 * B + 24 * C)) /
                   6.0f;
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
        if (ax->cdf[mid] <= u)
            lo = mid;
        else
            hi = mid;
    }
    float span = ax->cdf[lo + 1] - ax->cdf[lo];
    float t = span > 0.0f ? (u - ax->cdf[lo]) / span : 0.5f;
    float w = 2.0f * ax->radius / PN_FILTER_TABLE;
    *weight = ax->f[lo] >= 0.0f ? 1.0f : -1.0f;
    return -ax->radius + ((float)lo + t) * w;
}

/* ---- film response ------------------------------------------------------------------------ */

static void mat3_mul(const double a[3][3], const double b[3][3], double out[3][3]) {
    double r[3][3];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) r[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
    memcpy(out, r, sizeof r);
}

static void mat3_apply(const double m[3][3], const double v[3], double out[3]) {
    double r[3];
    for (int i = 0; i < 3; i++) r[i] = m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2];
    memcpy(out, r, sizeof r);
}

static bool mat3_inverse(const double m[3][3], double out[3][3]) {
    double c00 = m[1][1] * m[2][2] - m[1][2] * m[2][1], c01 = m[1][2] * m[2][0] - m[1][0] * m[2][2],
           c02 = m[1][0] * m[2][1] - m[1][1] * m[2][0];
    double det = m[0][0] * c00 + m[0][1] * c01 + m[0][2] * c02;
    if (!(fabs(det) > 0.0)) return false;
    double inv = 1.0 / det;
    out[0][0] = c00 * inv;
    out[0][1] = (m[0][2] * m[2][1] - m[0][1] * m[2][2]) * inv;
    out[0][2] = (m[0][1] * m[1][2] - m[0][2] * m[1][1]) * inv;
    out[1][0] = c01 * inv;
    out[1][1] = (m[0][0] * m[2][2] - m[0][2] * m[2][0]) * inv;
    out[1][2] = (m[0][2] * m[1][0] - m[0][0] * m[1][2]) * inv;
    out[2][0] = c02 * inv;
    out[2][1] = (m[0][1] * m[2][0] - m[0][0] * m[2][1]) * inv;
    out[2][2] = (m[0][0] * m[1][1] - m[0][1] * m[1][0]) * inv;
    return true;
}

static void xyz_of_xy(double x, double y, double out[3]) {
    out[0] = x / y;
    out[1] = 1.0;
    out[2] = (1.0 - x - y) / y;
}

/* sRGB's RGB -> XYZ from its primaries and D65 white, built as pbrt's RGBColorSpace does. */
static void srgb_xyz_from_rgb(double m[3][3]) {
    static const double prim[3][2] = {{0.64, 0.33}, {0.30, 0.60}, {0.15, 0.06}};
    double P[3][3], Pinv[3][3], W[3], S[3];
    for (int c = 0; c < 3; c++) {
        double v[3];
        xyz_of_xy(prim[c][0], prim[c][1], v);
        for (int r = 0; r < 3; r++) P[r][c] = v[r];
    }
    xyz_of_xy(0.3127, 0.3290, W);
    (void)mat3_inverse(P, Pinv);
    mat3_apply(Pinv, W, S);
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++) m[r][c] = P[r][c] * S[c];
}

void pn_white_balance_source_xy(double kelvin, double *x, double *y) {
    /* pbrt-v4 Spectra::D: the temperature is first turned into a correlated colour temperature
     * on the current c2 (1.4388/1.4380); below 4000 K the CIE daylight formula does not hold and
     * a blackbody is used. Daylight: the CIE daylight locus (CIE 15:2004, eq. 3.3-3.4); pbrt
     * integrates the spectrum reconstructed from S0, S1, S2 at these xy, whose chromaticity
     * differs from them by less than 1e-3. Blackbody: the Planckian locus by Kim et al.'s cubic
     * splines (US patent 7024034; within 1e-3 of the integrated locus). */
    double T = kelvin * 1.4388 / 1.4380;
    if (T >= 4000.0) {
        double t1 = 1e3 / T, t2 = t1 * t1, t3 = t2 * t1;
        double xd = T <= 7000.0 ? -4.6070 * t3 + 2.9678 * t2 + 0.09911 * t1 + 0.244063
                                : -2.0064 * t3 + 1.9018 * t2 + 0.24748 * t1 + 0.237040;
        *x = xd;
        *y = -3.0 * xd * xd + 2.870 * xd - 0.275;
        return;
    }
    double t1 = 1e3 / T, t2 = t1 * t1, t3 = t2 * t1;
    double xc = -0.2661239 * t3 - 0.2343589 * t2 + 0.8776956 * t1 + 0.179910;
    double x2 = xc * xc, x3 = x2 * xc;
    *x = xc;
    *y = T < 2222.0 ? -1.1063814 * x3 - 1.34811020 * x2 + 2.18555832 * xc - 0.20219683
                    : -0.9549476 * x3 - 1.37418593 * x2 + 2.09137015 * xc - 0.16748867;
}

void pn_white_balance_matrix(double kelvin, double out[3][3]) {
    static const double lms_from_xyz[3][3] = {
        {0.8951, 0.2664, -0.1614}, {-0.7502, 1.7135, 0.0367}, {0.0389, -0.0685, 1.0296}};
    double xyz_from_lms[3][3];
    (void)mat3_inverse(lms_from_xyz, xyz_from_lms);
    double sx, sy, src[3], dst[3], src_lms[3], dst_lms[3];
    pn_white_balance_source_xy(kelvin, &sx, &sy);
    xyz_of_xy(sx, sy, src);
    xyz_of_xy(0.3127, 0.3290, dst);
    mat3_apply(lms_from_xyz, src, src_lms);
    mat3_apply(lms_from_xyz, dst, dst_lms);
    double d[3][3] = {
        {dst_lms[0] / src_lms[0], 0, 0}, {0, dst_lms[1] / src_lms[1], 0}, {0, 0, dst_lms[2] / src_lms[2]}};
    double t[3][3];
    mat3_mul(d, lms_from_xyz, t);
    mat3_mul(xyz_from_lms, t, out);
}

static void film_setup(const pn_camera_def *def, pn_camera *cam) {
    cam->film_scale = def->imaging_ratio > 0.0f ? def->imaging_ratio : 1.0f;
    cam->film_max_component = def->max_component_value > 0.0f ? def->max_component_value : 0.0f;
    bool balance = def->white_balance_k > 0.0f;
    cam->film_matrix = balance || cam->film_max_component > 0.0f;
    cam->film_active = cam->film_matrix || cam->film_scale != 1.0f;
    if (!cam->film_matrix) return;
    srgb_xyz_from_rgb(cam->xyz_from_rgb);
    (void)mat3_inverse(cam->xyz_from_rgb, cam->rgb_from_xyz);
    if (balance) {
        pn_white_balance_matrix((double)def->white_balance_k, cam->white_balance);
    } else {
        memset(cam->white_balance, 0, sizeof cam->white_balance);
        for (int i = 0; i < 3; i++) cam->white_balance[i][i] = 1.0;
    }
}

void pn_camera_film_apply(const pn_camera *cam, pn_image image) {
    if (!cam->film_active || !image) return;
    /* the beauty layer belongs to the caller's image; its data is written in place */
    float *rgb = (float *)pn_image_layer_data(image, 0);
    if (!rgb) return;
    size_t n = (size_t)pn_image_width(image) * (size_t)pn_image_height(image);
    if (!cam->film_matrix) {
        for (size_t i = 0; i < 3 * n; i++) rgb[i] *= cam->film_scale;
        return;
    }
    /* The "cie1931" sensor records XYZ times the imaging ratio; RGBFilm clamps that sensor value
     * by its largest component and maps it to the output space through the white balance. */
    const double scale = (double)cam->film_scale, maxc = (double)cam->film_max_component;
    for (size_t i = 0; i < n; i++) {
        double c[3] = {rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2]}, xyz[3];
        mat3_apply(cam->xyz_from_rgb, c, xyz);
        for (int k = 0; k < 3; k++) xyz[k] *= scale;
        double m = fmax(xyz[0], fmax(xyz[1], xyz[2]));
        if (maxc > 0.0 && m > maxc)
            for (int k = 0; k < 3; k++) xyz[k] *= maxc / m;
        mat3_apply(cam->white_balance, xyz, xyz);
        mat3_apply(cam->rgb_from_xyz, xyz, c);
        for (int k = 0; k < 3; k++) rgb[3 * i + k] = (float)c[k];
    }
}

/* ---- camera ------------------------------------------------------------------------------- */

bool pn_camera_setup(const pn_camera_def *def, int full_width, int full_height, const float crop[4], pn_camera *cam) {
    memset(cam, 0, sizeof *cam);
    cam->world_from_camera = def->world_from_camera;
    if (!mat4_inverse(cam->world_from_camera, &cam->camera_from_world)) cam->camera_from_world = mat4_identity();
    cam->projection = def->projection;
    float fov = def->fov_deg > 0.0f ? def->fov_deg : 90.0f;
    cam->tan_half_fov = tanf(0.5f * fov * PN_PI / 180.0f);
    if (def->projection == PN_PROJECTION_EQUAL_AREA || def->projection == PN_PROJECTION_EQUIRECTANGULAR)
        cam->tan_half_fov = PN_PI * (float)(full_width < full_height ? full_width : full_height) / (float)full_width;
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
    if (def->pixel_bounds_given && full_width == def->width && full_height == def->height &&
        memcmp(crop, def->crop, sizeof def->crop) == 0) {
        cam->x0 = def->pixel_bounds[0];
        cam->x1 = def->pixel_bounds[1];
        cam->y0 = def->pixel_bounds[2];
        cam->y1 = def->pixel_bounds[3];
    }
    if (cam->x0 < 0) cam->x0 = 0;
    if (cam->y0 < 0) cam->y0 = 0;
    if (cam->x1 > full_width) cam->x1 = full_width;
    if (cam->y1 > full_height) cam->y1 = full_height;
    float rx = def->filter_radius[0] > 0.0f ? def->filter_radius[0] : 0.5f;
    float ry = def->filter_radius[1] > 0.0f ? def->filter_radius[1] : 0.5f;
    filter_axis_setup(def, rx, &cam->filter_x);
    filter_axis_setup(def, ry, &cam->filter_y);
    film_setup(def, cam);
    return cam->x1 > cam->x0 && cam->y1 > cam->y0;
}

void pn_camera_filter_sample(const pn_camera *cam, int px, int py, float u1, float u2, float *rx, float *ry,
                             float *weight) {
    float wx, wy;
    float dx = filter_axis_sample(&cam->filter_x, u1, &wx);
    float dy = filter_axis_sample(&cam->filter_y, u2, &wy);
    *rx = (float)px + 0.5f + dx;
    *ry = (float)py + 0.5f + dy;
    *weight = wx * wy;
}

/* pbrt-v4's spherical camera: (u, v) in [0,1]^2 of the full image to a camera-space direction,
 * the mappings' z axis becoming camera y (up). Filter samples outside the image wrap as
 * WrapEqualAreaSquare does for the equal-area square. */
static vec3 spherical_direction(const pn_camera *cam, float rx, float ry) {
    float u = rx / (float)cam->full_width, v = ry / (float)cam->full_height;
    vec3 d;
    if (cam->projection == PN_PROJECTION_EQUIRECTANGULAR) {
        float theta = PN_PI * v, phi = 2.0f * PN_PI * u;
        d = v3(sinf(theta) * cosf(phi), sinf(theta) * sinf(phi), cosf(theta));
    } else {
        if (u < 0.0f) {
            u = -u;
            v = 1.0f - v;
        } else if (u > 1.0f) {
            u = 2.0f - u;
            v = 1.0f - v;
        }
        if (v < 0.0f) {
            u = 1.0f - u;
            v = -v;
        } else if (v > 1.0f) {
            u = 1.0f - u;
            v = 2.0f - v;
        }
        d = pn_equal_area_square_to_sphere(u, v);
    }
    return v3(d.x, d.z, d.y);
}

void pn_camera_ray(const pn_camera *cam, float rx, float ry, float l1, float l2, vec3 *origin, vec3 *dir) {
    if (cam->projection == PN_PROJECTION_EQUAL_AREA || cam->projection == PN_PROJECTION_EQUIRECTANGULAR) {
        *origin = mat4_apply_point(&cam->world_from_camera, v3(0, 0, 0));
        *dir = v3_normalize(mat4_apply_vector(&cam->world_from_camera, spherical_direction(cam, rx, ry)));
        return;
    }
    /* Raster to screen: x grows right, raster y grows down while screen y grows up. */
    float sx = cam->screen[0] + (rx / (float)cam->full_width) * (cam->screen[1] - cam->screen[0]);
    float sy = cam->screen[3] - (ry / (float)cam->full_height) * (cam->screen[3] - cam->screen[2]);
    const bool ortho = cam->projection == PN_PROJECTION_ORTHOGRAPHIC;
    /* orthographic: from the screen point at z = 0 along +z (pbrt's Orthographic(0, 1)) */
    vec3 d = ortho ? v3(0.0f, 0.0f, 1.0f) : v3(sx * cam->tan_half_fov, sy * cam->tan_half_fov, 1.0f);
    vec3 o = ortho ? v3(sx, sy, 0.0f) : v3(0, 0, 0);
    if (cam->lens_radius > 0.0f) {
        /* Thin lens: concentric disk sample on the lens, focus on the plane z = focal_distance.
         * As in pbrt-v4, the ray then starts on the lens around the camera's axis, also for the
         * orthographic camera (whose focus point is the screen point at that depth). */
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
        vec3 focus = ortho ? v3(sx, sy, cam->focal_distance) : v3_scale(d, cam->focal_distance / d.z);
        o = lens;
        d = v3_sub(focus, lens);
    }
    *origin = mat4_apply_point(&cam->world_from_camera, o);
    *dir = v3_normalize(mat4_apply_vector(&cam->world_from_camera, d));
}

bool pn_camera_differentials(const pn_camera *cam, vec3 o, vec3 d, float scale, vec3 *ox, vec3 *dx, vec3 *oy,
                             vec3 *dy) {
    if (cam->projection == PN_PROJECTION_EQUAL_AREA || cam->projection == PN_PROJECTION_EQUIRECTANGULAR) return false;
    const bool ortho = cam->projection == PN_PROJECTION_ORTHOGRAPHIC;
    vec3 oc = mat4_apply_point(&cam->camera_from_world, o), dc = mat4_apply_vector(&cam->camera_from_world, d);
    if (!(dc.z > 0.0f)) return false;
    /* One raster pixel in camera units: on the plane z = 1 (perspective) or of the screen
     * (orthographic); raster y grows down. */
    float k = ortho ? 1.0f : cam->tan_half_fov;
    vec3 step[2] = {v3(k * (cam->screen[1] - cam->screen[0]) / (float)cam->full_width, 0.0f, 0.0f),
                    v3(0.0f, -k * (cam->screen[3] - cam->screen[2]) / (float)cam->full_height, 0.0f)};
    vec3 *out_o[2] = {ox, oy}, *out_d[2] = {dx, dy};
    vec3 dn = v3_normalize(dc);
    for (int a = 0; a < 2; a++) {
        vec3 ro = oc, rd;
        if (cam->lens_radius > 0.0f) {
            /* The same lens point, towards the shifted pixel's point on the plane of focus. */
            vec3 focus = v3_madd(oc, dc, (cam->focal_distance - oc.z) / dc.z);
            vec3 shifted = ortho ? v3_add(focus, step[a]) : v3_add(focus, v3_scale(step[a], cam->focal_distance));
            rd = v3_normalize(v3_sub(shifted, oc));
        } else if (ortho) {
            ro = v3_add(oc, step[a]);
            rd = dn;
        } else {
            rd = v3_normalize(v3_add(v3_scale(dc, 1.0f / dc.z), step[a]));
        }
        /* pbrt-v4 RayDifferential::ScaleDifferentials */
        ro = v3_add(oc, v3_scale(v3_sub(ro, oc), scale));
        rd = v3_add(dn, v3_scale(v3_sub(rd, dn), scale));
        *out_o[a] = mat4_apply_point(&cam->world_from_camera, ro);
        *out_d[a] = mat4_apply_vector(&cam->world_from_camera, rd);
    }
    return true;
}
