/* report.c — what `penumbra render` tells about a run: the summary on stdout and the statistics
 * JSON (docs/stats-json.md), written with cJSON into the run's output set (pn_output_set_add_file,
 * renamed into place with the image). Both name the integrator and driver and every resolved option of
 * theirs, from the method table, so that a run can be reproduced from its own JSON. */
#include "cli/cli.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

/* Version of the JSON layout; docs/stats-json.md says what changed. */
#define STATS_SCHEMA_VERSION 2

/* The spp and threshold in force (0 when they do not apply). */
static uint32_t resolved_spp(const render_options *o) {
    const pn_method_info *mi = pn_method_get(o->integrator);
    if (!(mi->capabilities & PN_CAP_SPP)) return 0;
    return o->settings.spp ? o->settings.spp : mi->default_spp;
}

static double resolved_threshold(const render_options *o) {
    const pn_method_info *mi = pn_method_get(o->integrator);
    if (!(mi->capabilities & PN_CAP_THRESHOLD) || resolved_spp(o)) return 0.0;
    return o->settings.threshold > 0.0 ? o->settings.threshold : 0.01;
}

char *json_print(const void *tree) {
    char *text = cJSON_Print((const cJSON *)tree);
    if (!text) return NULL;
    /* cJSON indents with tabs and writes "key":<tab>value; strings escape their own tabs, so a
     * raw tab is always layout: two spaces for indentation, one after a colon. */
    size_t n = strlen(text), tabs = 0;
    for (size_t i = 0; i < n; i++) tabs += text[i] == '\t';
    char *out = malloc(n + tabs + 2);
    if (!out) {
        cJSON_free(text);
        return NULL;
    }
    size_t j = 0;
    for (size_t i = 0; i < n; i++) {
        if (text[i] != '\t')
            out[j++] = text[i];
        else if (i > 0 && text[i - 1] == ':')
            out[j++] = ' ';
        else {
            out[j++] = ' ';
            out[j++] = ' ';
        }
    }
    out[j++] = '\n';
    out[j] = '\0';
    cJSON_free(text);
    return out;
}

/* Every resolved option of the chosen integrator and driver, by name. */
static cJSON *options_json(const render_options *o) {
    cJSON *obj = cJSON_CreateObject();
    for (int i = 0; obj && i < pn_option_count(); i++) {
        if (!pn_option_applies(i, o->integrator) && !pn_option_applies(i, o->driver)) continue;
        const pn_option_info *info = pn_option_get(i);
        double number = 0.0;
        char text[1024] = "";
        pn_options_get(o->options, i, &number, text, sizeof text);
        switch (info->type) {
        case PN_OPTION_INT:
        case PN_OPTION_DOUBLE: cJSON_AddNumberToObject(obj, info->name, number); break;
        case PN_OPTION_FLAG: cJSON_AddBoolToObject(obj, info->name, number != 0.0); break;
        default: cJSON_AddStringToObject(obj, info->name, text); break;
        }
    }
    return obj;
}

static cJSON *number_array(const double *v, int n) {
    return cJSON_CreateDoubleArray(v, n);
}

static cJSON *scene_info_json(const pn_scene_info *info, pn_scene scene) {
    cJSON *si = cJSON_CreateObject();
    cJSON_AddNumberToObject(si, "triangles", (double)info->triangles);
    cJSON_AddNumberToObject(si, "unique_triangles", (double)info->unique_triangles);
    cJSON_AddNumberToObject(si, "meshes", info->meshes);
    cJSON_AddNumberToObject(si, "instances", info->instances);
    cJSON_AddNumberToObject(si, "spheres", info->spheres);
    cJSON *lights = cJSON_AddObjectToObject(si, "lights");
    cJSON_AddNumberToObject(lights, "point", info->lights_point);
    cJSON_AddNumberToObject(lights, "spot", info->lights_spot);
    cJSON_AddNumberToObject(lights, "distant", info->lights_distant);
    cJSON_AddNumberToObject(lights, "infinite", info->lights_infinite);
    cJSON_AddNumberToObject(lights, "goniometric", info->lights_goniometric);
    cJSON_AddNumberToObject(lights, "projection", info->lights_projection);
    cJSON_AddNumberToObject(lights, "area_triangle", info->lights_area_triangle);
    cJSON_AddNumberToObject(lights, "area_rectangle", info->lights_area_rectangle);
    cJSON_AddNumberToObject(lights, "area_disk", info->lights_area_disk);
    cJSON_AddNumberToObject(lights, "area_sphere", info->lights_area_sphere);
    cJSON_AddNumberToObject(si, "materials", info->materials);
    cJSON_AddNumberToObject(si, "textures", info->textures);
    cJSON_AddNumberToObject(si, "warnings", info->warnings);
    double bmin[3], bmax[3], film[2] = {info->resolution[0], info->resolution[1]};
    for (int i = 0; i < 3; i++) {
        bmin[i] = (double)info->bounds_min[i];
        bmax[i] = (double)info->bounds_max[i];
    }
    cJSON_AddItemToObject(si, "bounds_min", number_array(bmin, 3));
    cJSON_AddItemToObject(si, "bounds_max", number_array(bmax, 3));
    cJSON_AddItemToObject(si, "film_resolution", number_array(film, 2));
    cJSON_AddNumberToObject(si, "parse_seconds", info->parse_seconds);
    cJSON_AddNumberToObject(si, "bvh_seconds", info->bvh_seconds);
    cJSON *mapping = cJSON_AddArrayToObject(si, "material_mapping");
    uint32_t count = pn_scene_material_count(scene);
    for (uint32_t i = 0; i < count; i++)
        cJSON_AddItemToArray(mapping, cJSON_CreateString(pn_scene_material_description(scene, i)));
    return si;
}

static void add_string_or_null(cJSON *obj, const char *key, const char *value) {
    if (value)
        cJSON_AddStringToObject(obj, key, value);
    else
        cJSON_AddNullToObject(obj, key);
}

int write_stats_json(const render_options *o, pn_output_set outputs, const char *image_path, pn_scene scene,
                     const pn_scene_info *info, pn_stats stats, int interrupted_render) {
    const pn_render_settings *st = &o->settings;
    const pn_method_info *mi = pn_method_get(o->integrator), *md = pn_method_get(o->driver);
    cJSON *root = cJSON_CreateObject();
    cJSON_AddNumberToObject(root, "schema_version", STATS_SCHEMA_VERSION);
    cJSON_AddStringToObject(root, "penumbra_version", pn_version_string());
    cJSON_AddStringToObject(root, "scene", o->scene_path);
    add_string_or_null(root, "image", image_path);
    add_string_or_null(root, "png", o->png_path);
    cJSON_AddBoolToObject(root, "interrupted", interrupted_render);

    cJSON *set = cJSON_AddObjectToObject(root, "settings");
    cJSON_AddStringToObject(set, "integrator", mi->name);
    cJSON_AddStringToObject(set, "driver", md->name);
    cJSON_AddStringToObject(set, "computes", mi->computes);
    uint32_t spp = resolved_spp(o);
    double threshold = resolved_threshold(o);
    if (spp)
        cJSON_AddNumberToObject(set, "spp", spp);
    else
        cJSON_AddNullToObject(set, "spp");
    if (threshold > 0.0)
        cJSON_AddNumberToObject(set, "threshold", threshold);
    else
        cJSON_AddNullToObject(set, "threshold");
    if (st->width) {
        double res[2] = {st->width, st->height};
        cJSON_AddItemToObject(set, "resolution", number_array(res, 2));
    } else {
        cJSON_AddNullToObject(set, "resolution");
    }
    if (st->has_crop) {
        double crop[4];
        for (int i = 0; i < 4; i++) crop[i] = (double)st->crop[i];
        cJSON_AddItemToObject(set, "crop", number_array(crop, 4));
    } else {
        cJSON_AddNullToObject(set, "crop");
    }
    cJSON_AddNumberToObject(set, "threads", st->threads);
    /* A 64-bit seed does not fit a JSON number exactly: text. */
    char seed[32];
    snprintf(seed, sizeof seed, "%llu", (unsigned long long)st->seed);
    cJSON_AddStringToObject(set, "seed", seed);
    cJSON *aovs = cJSON_AddArrayToObject(set, "aovs");
    uint32_t bit;
    for (int i = 0; pn_aov_name(i, &bit); i++)
        if (st->aovs & bit) cJSON_AddItemToArray(aovs, cJSON_CreateString(pn_aov_name(i, NULL)));
    cJSON_AddNumberToObject(set, "exposure", o->exposure);
    cJSON_AddItemToObject(set, "options", options_json(o));

    /* Every statistic of the table (render/stats.c) that the render produced, in table order. */
    cJSON *sj = cJSON_AddObjectToObject(root, "stats");
    for (int i = 0; i < pn_stat_count(); i++) {
        const pn_stat_info *si = pn_stat_get(i);
        double v = 0.0;
        if (si->per_rank) {
            int n = pn_stats_get_array(stats, si->name, NULL, 0);
            double *values = n > 0 ? malloc((size_t)n * sizeof *values) : NULL;
            if (!values) continue;
            pn_stats_get_array(stats, si->name, values, n);
            cJSON_AddItemToObject(sj, si->name, cJSON_CreateDoubleArray(values, n));
            free(values);
        } else if (pn_stats_get(stats, si->name, &v)) {
            if (si->type == PN_STAT_FLAG)
                cJSON_AddBoolToObject(sj, si->name, v != 0.0);
            else
                cJSON_AddNumberToObject(sj, si->name, v);
        }
    }
    cJSON_AddItemToObject(root, "scene_info", scene_info_json(info, scene));

    char *text = json_print(root);
    cJSON_Delete(root);
    if (!text) {
        fprintf(stderr, "penumbra: out of memory for the statistics\n");
        return EXIT_SYSTEM;
    }
    pn_context ctx = pn_context_new();
    pn_status status =
        ctx ? pn_output_set_add_file(ctx, outputs, o->stats_path, text, strlen(text)) : PN_ERROR_OUT_OF_MEMORY;
    int code = EXIT_OK;
    if (status != PN_OK) {
        fprintf(stderr, "penumbra: cannot write '%s': %s\n", o->stats_path,
                ctx ? pn_context_error_message(ctx) : "out of memory");
        code = EXIT_SYSTEM;
    }
    pn_context_free(ctx);
    free(text);
    return code;
}

static void print_count(const char *label, uint64_t value) {
    printf("%-14s %llu\n", label, (unsigned long long)value);
}

/* "name value, name value, ..." of the resolved options of method m. */
static void print_options_line(const render_options *o, int m) {
    const pn_method_info *info = pn_method_get(m);
    printf("%-14s %s: %s", info->role == PN_METHOD_DRIVER ? "driver" : "integrator", info->name, info->computes);
    int n = 0;
    for (int i = 0; i < pn_option_count(); i++) {
        if (!pn_option_applies(i, m)) continue;
        char text[256] = "";
        pn_options_get(o->options, i, NULL, text, sizeof text);
        printf("%s%s %s", n++ ? ", " : "\n  options      ", pn_option_get(i)->name, text[0] ? text : "(none)");
    }
    printf("\n");
}

/* The statistic `name` of the render, 0 when it did not produce it. */
static double stat(pn_stats stats, const char *name) {
    double v = 0.0;
    return pn_stats_get(stats, name, &v) ? v : 0.0;
}

static unsigned long long stat_u(pn_stats stats, const char *name) {
    return (unsigned long long)stat(stats, name);
}

void print_render_summary(const render_options *o, const pn_scene_info *info, pn_stats stats, const char *image_path) {
    printf("scene          %s\n", o->scene_path);
    print_options_line(o, o->integrator);
    print_options_line(o, o->driver);
    printf("resolution     %dx%d", (int)stat(stats, "width"), (int)stat(stats, "height"));
    if (o->settings.has_crop)
        printf(" (crop %g,%g,%g,%g)", (double)o->settings.crop[0], (double)o->settings.crop[1],
               (double)o->settings.crop[2], (double)o->settings.crop[3]);
    printf("\n");
    uint32_t spp = resolved_spp(o);
    double threshold = resolved_threshold(o);
    if (spp)
        printf("sampling       %u eye rays/pixel\n", spp);
    else if (threshold > 0.0)
        printf("sampling       adaptive, threshold %g\n", threshold);
    printf("time           parse %.2f s, BVH %.2f s, render %.2f s (%d threads)\n", info->parse_seconds,
           info->bvh_seconds, stat(stats, "render_seconds"), (int)stat(stats, "threads"));
    if (stat_u(stats, "tiles_resumed"))
        printf("resumed        %llu of %llu tiles from the checkpoint\n", stat_u(stats, "tiles_resumed"),
               stat_u(stats, "tile_count"));
    int ranks = (int)stat(stats, "ranks");
    if (ranks > 1) {
        double *busy = malloc((size_t)ranks * sizeof *busy), *tiles = malloc((size_t)ranks * sizeof *tiles);
        int n = busy && tiles ? pn_stats_get_array(stats, "rank_busy_seconds", busy, ranks) : 0;
        if (n > 0) n = pn_stats_get_array(stats, "rank_tiles", tiles, ranks);
        printf("ranks          %d, busy", ranks);
        for (int r = 0; r < n && r < ranks; r++)
            printf("%s %.2f s (%llu tiles)", r ? "," : "", busy[r], (unsigned long long)tiles[r]);
        printf("\n");
        free(busy);
        free(tiles);
    }
    print_count("eye rays", stat_u(stats, "eye_rays"));
    print_count("shadow rays", stat_u(stats, "shadow_rays"));
    print_count("specular rays", stat_u(stats, "specular_rays"));
    printf("eye/pixel      mean %.2f, max %llu\n", stat(stats, "eye_rays_per_pixel_mean"),
           stat_u(stats, "eye_rays_per_pixel_max"));
    printf("shadow/pixel   mean %.1f, max %llu\n", stat(stats, "shadow_rays_per_pixel_mean"),
           stat_u(stats, "shadow_rays_per_pixel_max"));
    printf("speed          %.2f Mrays/s\n", stat(stats, "mrays_per_second"));
    if (stat_u(stats, "vpl_count"))
        printf("VPLs           %llu (%llu paths), preprocessing %.2f s (VPLs %.2f s, light tree %.2f s), "
               "bounds/pixel %.1f\n",
               stat_u(stats, "vpl_count"), stat_u(stats, "vpl_paths"), stat(stats, "preprocess_seconds"),
               stat(stats, "vpl_seconds"), stat(stats, "light_tree_seconds"),
               stat(stats, "bound_evaluations_per_pixel_mean"));
    printf("peak memory    %.1f MiB\n", stat(stats, "peak_memory_bytes") / (1024.0 * 1024.0));
    printf("wrote          %s", image_path);
    if (o->png_path) printf(", %s", o->png_path);
    if (o->stats_path) printf(", %s", o->stats_path);
    printf("\n");
}
