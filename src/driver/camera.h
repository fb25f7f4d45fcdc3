/* camera.h — pbrt-v4's perspective camera (fov on the shorter axis, screen window, thin lens)
 * and the pixel filters, importance-sampled as pbrt-v4's FilterSampler does. */
#ifndef PN_DRIVER_CAMERA_H
#define PN_DRIVER_CAMERA_H

#include "core/vecmath.h"
#include "scene/scene.h"

#define PN_FILTER_TABLE 64

/* A separable 1D filter tabulated on [-radius, radius] for importance sampling by |f|. */
typedef struct pn_filter_axis {
    float radius;
    float f[PN_FILTER_TABLE];   /* filter value at bin centres */
    float cdf[PN_FILTER_TABLE + 1];
    float integral_abs;         /* integral of |f| over the bins */
} pn_filter_axis;

typedef struct pn_camera {
    mat4 world_from_camera;
    float tan_half_fov;
    float screen[4];            /* xmin xmax ymin ymax */
    float lens_radius, focal_distance;
    int full_width, full_height; /* resolution of the whole image */
    int x0, y0, x1, y1;          /* pixel bounds of the rendered window [x0,x1) x [y0,y1) */
    pn_filter_axis filter_x, filter_y;
} pn_camera;

/* Sets up the camera for an image of full_width x full_height and a crop window in fractions
 * (pbrt's rounding: pixel bounds are ceil(res * crop)). Returns false for an empty window. */
bool pn_camera_setup(const pn_camera_def *def, int full_width, int full_height, const float crop[4],
                     pn_camera *cam);

/* Samples the pixel filter around the centre of pixel (px, py) with u in [0,1)^2: returns the
 * raster position and the sample's weight (1 for non-negative filters). */
void pn_camera_filter_sample(const pn_camera *cam, int px, int py, float u1, float u2, float *rx,
                             float *ry, float *weight);

/* A primary ray through raster position (rx, ry) with lens sample (l1, l2). The direction is
 * unit length. */
void pn_camera_ray(const pn_camera *cam, float rx, float ry, float l1, float l2, vec3 *origin, vec3 *dir);

#endif
