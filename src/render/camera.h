/* camera.h — pbrt-v4's cameras (perspective: fov on the shorter axis, screen window, thin lens;
 * orthographic; spherical, equal-area or equirectangular), the pixel filters, importance-sampled
 * as pbrt-v4's FilterSampler does, and the film's response (imaging ratio, clamp, white
 * balance), applied to the finished image in one place. */
#ifndef PN_RENDER_CAMERA_H
#define PN_RENDER_CAMERA_H

#include "core/vecmath.h"
#include "scene/scene.h"

#define PN_FILTER_TABLE 64

/* A separable 1D filter tabulated on [-radius, radius] for importance sampling by |f|. */
typedef struct pn_filter_axis {
    float radius;
    float f[PN_FILTER_TABLE]; /* filter value at bin centres */
    float cdf[PN_FILTER_TABLE + 1];
    float integral_abs; /* integral of |f| over the bins */
} pn_filter_axis;

typedef struct pn_camera {
    mat4 world_from_camera;
    mat4 camera_from_world;
    pn_camera_projection projection;
    float tan_half_fov; /* perspective; for the others the value that makes 2 tan / min(w, h)
                                   the angle of a pixel (ias's heuristics read it) */
    float screen[4];    /* xmin xmax ymin ymax */
    float lens_radius, focal_distance;
    int full_width, full_height; /* resolution of the whole image */
    int x0, y0, x1, y1;          /* pixel bounds of the rendered window [x0,x1) x [y0,y1) */
    pn_filter_axis filter_x, filter_y;
    /* The film's response (pn_camera_def): false = the image is left exactly as rendered. */
    bool film_active;
    bool film_matrix;         /* clamp or white balance: go through XYZ */
    float film_scale;         /* the imaging ratio */
    float film_max_component; /* 0 = no clamp */
    double xyz_from_rgb[3][3], rgb_from_xyz[3][3], white_balance[3][3];
} pn_camera;

/* The ray differentials of camera ray (o, d) (as pn_camera_ray made it) as pbrt-v4's cameras
 * make them: the rays through the raster points one pixel to the right (x) and down (y), with
 * the same lens point, then scaled about the ray by `scale` (pbrt: max(1/8, 1/sqrt(spp))).
 * Perspective and orthographic cameras; false (no differentials) for the spherical ones. */
bool pn_camera_differentials(const pn_camera *cam, vec3 o, vec3 d, float scale, vec3 *ox, vec3 *dx, vec3 *oy, vec3 *dy);

/* Sets up the camera for an image of full_width x full_height and a crop window in fractions
 * (pbrt's rounding: pixel bounds are ceil(res * crop)). When the scene gave Film "pixelbounds"
 * and the crop and resolution are the scene's own, its integer window is used as it is.
 * Returns false for an empty window. */
bool pn_camera_setup(const pn_camera_def *def, int full_width, int full_height, const float crop[4], pn_camera *cam);

/* Samples the pixel filter around the centre of pixel (px, py) with u in [0,1)^2: returns the
 * raster position and the sample's weight (1 for non-negative filters). */
void pn_camera_filter_sample(const pn_camera *cam, int px, int py, float u1, float u2, float *rx, float *ry,
                             float *weight);

/* A primary ray through raster position (rx, ry) with lens sample (l1, l2). The direction is
 * unit length. */
void pn_camera_ray(const pn_camera *cam, float rx, float ry, float l1, float l2, vec3 *origin, vec3 *dir);

/* The film's response, applied once to the beauty layer (layer 0) of a finished image: this is
 * the one place where penumbra changes the image's scale. pbrt-v4 clamps each sample's sensor
 * value (RGBFilm::AddSample); penumbra clamps each pixel's estimate, whose value is then the
 * same bound. Does nothing for pbrt's defaults (iso 100, a shutter open for 1, no clamp, no
 * white balance), so such images are bit-identical to the renderer's estimate. */
void pn_camera_film_apply(const pn_camera *cam, pn_image image);

/* The matrix (XYZ to XYZ) that white-balances a scene lit by the CIE daylight illuminant of
 * colour temperature `kelvin` (below 4000 K a blackbody, as pbrt-v4's Spectra::D) to the sRGB
 * (D65) white, by the Bradford von Kries transform (pbrt-v4 WhiteBalance). */
void pn_white_balance_matrix(double kelvin, double out[3][3]);

/* The chromaticity pbrt-v4 takes for its white-balance source illuminant at `kelvin`. */
void pn_white_balance_source_xy(double kelvin, double *x, double *y);

#endif
