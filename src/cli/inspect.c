/* inspect.c — `penumbra diff` (image metrics) and `penumbra info` (what penumbra made of a scene). */
#include "cli/cli.h"

#include <cjson/cJSON.h>
#include <stdlib.h>
#include <string.h>

/* ---------------------------------------------------------------------------------------- */
/* diff */

int command_diff(int argc, char **argv) {
    const char *cmd = "diff";
    const char *paths[2] = {NULL, NULL};
    const char *error_path = NULL, *positional = NULL, *value;
    int json = 0, count = 0, kind;
    uint64_t max_pixels = 0; /* --max-image-pixels; 0 = the default */
    arg_scanner s = {cmd, argc, argv, 0, {0}, NULL, 0};
    while ((kind = scanner_next(&s, &positional)) != 0) {
        if (kind == 2) {
            if (count >= 2) return usage_error(cmd, "unexpected argument '%s'", positional);
            paths[count++] = positional;
        } else if (strcmp(s.name, "-h") == 0 || strcmp(s.name, "--help") == 0) {
            fputs(diff_help, stdout);
            return EXIT_OK;
        } else if (strcmp(s.name, "--max-image-pixels") == 0) {
            if ((value = scanner_value(&s)) == NULL || !parse_pixel_limit(cmd, s.name, value, &max_pixels))
                return EXIT_USAGE;
        } else if (strcmp(s.name, "--json") == 0) {
            if (!scanner_no_value(&s)) return EXIT_USAGE;
            json = 1;
        } else if (strcmp(s.name, "--error-image") == 0) {
            if ((value = scanner_value(&s)) == NULL) return EXIT_USAGE;
            if (!is_writable_image_name(value))
                return bad_value(cmd, s.name, value, "a file name ending in .exr, .pfm or .png");
            error_path = value;
        } else {
            return usage_error(cmd, "unknown option '%s'", s.argv[s.index]);
        }
    }
    if (count < 2) return usage_error(cmd, "needs two images, REFERENCE and IMAGE");
    int code;
    if ((code = check_input_file(paths[0])) != EXIT_OK || (code = check_input_file(paths[1])) != EXIT_OK) return code;
    if (error_path && (code = check_output_folder(error_path)) != EXIT_OK) return code;

    pn_context ctx = pn_context_new();
    if (ctx == NULL) {
        fprintf(stderr, "penumbra: out of memory\n");
        return EXIT_SYSTEM;
    }
    log_options log = {0, 1};
    pn_context_set_log(ctx, on_log, &log);
    pn_context_set_image_pixel_limit(ctx, max_pixels);
    pn_image reference = NULL, image = NULL, error_image = NULL;
    pn_image_metrics m;
    memset(&m, 0, sizeof m);
    pn_status status = pn_image_read(ctx, paths[0], &reference);
    if (status == PN_OK) status = pn_image_read(ctx, paths[1], &image);
    if (status != PN_OK) {
        code = report_failure(ctx, status);
        goto done;
    }
    int rw = pn_image_width(reference), rh = pn_image_height(reference);
    int iw = pn_image_width(image), ih = pn_image_height(image);
    if (rw != iw || rh != ih) {
        fprintf(stderr, "penumbra: image sizes differ: '%s' is %dx%d, '%s' is %dx%d\n", paths[0], rw, rh, paths[1], iw,
                ih);
        code = EXIT_BAD_INPUT;
        goto done;
    }
    status = pn_image_compare(ctx, reference, image, &m, error_path ? &error_image : NULL);
    if (status != PN_OK) {
        code = report_failure(ctx, status);
        goto done;
    }
    if (error_path && (status = pn_image_write(ctx, error_image, error_path, 0.0f)) != PN_OK) {
        code = report_failure(ctx, status);
        goto done;
    }
    if (json) {
        cJSON *root = cJSON_CreateObject();
        cJSON_AddStringToObject(root, "reference", paths[0]); /* not-a-method-name: the image */
        cJSON_AddStringToObject(root, "image", paths[1]);
        cJSON_AddNumberToObject(root, "width", rw);
        cJSON_AddNumberToObject(root, "height", rh);
        cJSON_AddNumberToObject(root, "rmse", m.rmse);
        cJSON_AddNumberToObject(root, "relmse", m.relmse);
        cJSON_AddNumberToObject(root, "relmse_epsilon", m.relmse_epsilon);
        cJSON_AddNumberToObject(root, "rel_l1", m.rel_l1);
        cJSON_AddNumberToObject(root, "rel_l2", m.rel_l2);
        cJSON_AddNumberToObject(root, "mae", m.mae);
        cJSON_AddNumberToObject(root, "mean_luminance_reference", m.mean_luminance_reference);
        cJSON_AddNumberToObject(root, "mean_luminance_image", m.mean_luminance_image);
        if (error_path)
            cJSON_AddStringToObject(root, "error_image", error_path);
        else
            cJSON_AddNullToObject(root, "error_image");
        char *text = json_print(root);
        cJSON_Delete(root);
        if (text) fputs(text, stdout);
        free(text);
    } else {
        printf("reference      %s (%dx%d)\n", paths[0], rw, rh);
        printf("image          %s\n", paths[1]);
        printf("RMSE           %.6g\n", m.rmse);
        printf("relMSE         %.6g (epsilon %g)\n", m.relmse, m.relmse_epsilon);
        printf("rel L1         %.6g\n", m.rel_l1);
        printf("rel L2         %.6g\n", m.rel_l2);
        printf("MAE            %.6g\n", m.mae);
        printf("mean luminance reference %.6g, image %.6g\n", m.mean_luminance_reference, m.mean_luminance_image);
        if (error_path) printf("error image    %s (|image - reference| x 16)\n", error_path);
    }
    code = EXIT_OK;

done:
    pn_image_free(error_image);
    pn_image_free(image);
    pn_image_free(reference);
    pn_context_free(ctx);
    return code;
}

/* ---------------------------------------------------------------------------------------- */
/* info */

/* Measured luminaires: the lumens each emits, integrated from its distribution, next to what
 * its file states (docs/luminaires.md). */
static void print_luminaires(pn_scene scene) {
    uint32_t n = pn_scene_luminaire_count(scene);
    if (!n) return;
    printf("luminaires     %u (lumens integrated from the distribution; stated by the file)\n", n);
    for (uint32_t i = 0; i < n; i++) {
        pn_luminaire_info li;
        if (pn_scene_luminaire_get(scene, i, &li) != PN_OK) continue;
        const char *base = strrchr(li.file, '/');
        base = base ? base + 1 : li.file;
        printf("  %s %s: %.1f lm emitted, peak %.1f cd; file %.1f lm integrated", li.source, base, li.lumens,
               li.peak_candela, li.file_lumens);
        if (li.stated_lumens < 0.0)
            printf(", absolute photometry (no lamp lumens stated)");
        else
            printf(", %.1f lm of lamps stated", li.stated_lumens);
        if (li.stated_luminaire_lumens >= 0.0) printf(", %.1f lm luminaire (LOR) stated", li.stated_luminaire_lumens);
        printf("\n");
    }
}

int command_info(int argc, char **argv) {
    const char *cmd = "info";
    const char *scene_path = NULL, *positional = NULL;
    uint64_t max_pixels = 0;
    int kind;
    arg_scanner s = {cmd, argc, argv, 0, {0}, NULL, 0};
    while ((kind = scanner_next(&s, &positional)) != 0) {
        if (kind == 2) {
            if (scene_path) return usage_error(cmd, "unexpected argument '%s'", positional);
            scene_path = positional;
        } else if (strcmp(s.name, "-h") == 0 || strcmp(s.name, "--help") == 0) {
            fputs(info_help, stdout);
            return EXIT_OK;
        } else if (strcmp(s.name, "--max-image-pixels") == 0) {
            const char *value = scanner_value(&s);
            if (value == NULL || !parse_pixel_limit(cmd, s.name, value, &max_pixels)) return EXIT_USAGE;
        } else {
            return usage_error(cmd, "unknown option '%s'", s.argv[s.index]);
        }
    }
    if (scene_path == NULL) return usage_error(cmd, "missing the scene file");

    pn_context ctx = pn_context_new();
    if (ctx == NULL) {
        fprintf(stderr, "penumbra: out of memory\n");
        return EXIT_SYSTEM;
    }
    /* Warnings are listed in the report, so the log need not print them too. */
    log_options log = {1, 0};
    pn_context_set_log(ctx, on_log, &log);
    pn_context_set_image_pixel_limit(ctx, max_pixels);
    pn_scene scene = NULL;
    pn_scene_info info;
    memset(&info, 0, sizeof info);
    int code;
    pn_status status = pn_scene_load(ctx, scene_path, &scene);
    if (status == PN_OK) status = pn_scene_get_info(scene, &info);
    if (status != PN_OK) {
        code = report_failure(ctx, status);
        goto done;
    }

    uint64_t area = (uint64_t)info.lights_area_triangle + info.lights_area_rectangle + info.lights_area_disk +
                    info.lights_area_sphere;
    uint64_t lights = area + info.lights_point + info.lights_spot + info.lights_distant + info.lights_infinite +
                      info.lights_goniometric + info.lights_projection;
    printf("scene          %s\n", scene_path);
    printf("film           %dx%d\n", info.resolution[0], info.resolution[1]);
    printf("triangles      %llu (%llu unique)\n", (unsigned long long)info.triangles,
           (unsigned long long)info.unique_triangles);
    printf("meshes         %u\n", info.meshes);
    printf("instances      %u\n", info.instances);
    printf("spheres        %u\n", info.spheres);
    printf("lights         %llu\n", (unsigned long long)lights);
    printf("  point        %u\n", info.lights_point);
    printf("  spot         %u\n", info.lights_spot);
    printf("  distant      %u\n", info.lights_distant);
    printf("  infinite     %u\n", info.lights_infinite);
    printf("  goniometric  %u\n", info.lights_goniometric);
    printf("  projection   %u\n", info.lights_projection);
    printf("  area         %llu (triangle %u, rectangle %u, disk %u, sphere %u)\n", (unsigned long long)area,
           info.lights_area_triangle, info.lights_area_rectangle, info.lights_area_disk, info.lights_area_sphere);
    print_luminaires(scene);
    uint32_t material_count = pn_scene_material_count(scene);
    printf("materials      %u\n", info.materials);
    for (uint32_t i = 0; i < material_count; i++) {
        const char *line = pn_scene_material_description(scene, i);
        printf("  %s\n", line ? line : "");
    }
    printf("textures       %u (%u images decoded, %.1f MiB with the pyramids)\n", info.textures, info.texture_images,
           (double)info.texture_bytes / (1024.0 * 1024.0));
    printf("bounds         (%g, %g, %g) to (%g, %g, %g)\n", (double)info.bounds_min[0], (double)info.bounds_min[1],
           (double)info.bounds_min[2], (double)info.bounds_max[0], (double)info.bounds_max[1],
           (double)info.bounds_max[2]);
    printf("load time      parse %.3f s, BVH %.3f s\n", info.parse_seconds, info.bvh_seconds);
    uint32_t warning_count = pn_scene_warning_count(scene);
    printf("warnings       %u\n", warning_count);
    for (uint32_t i = 0; i < warning_count; i++) {
        const char *line = pn_scene_warning(scene, i);
        printf("  %s\n", line ? line : "");
    }
    code = EXIT_OK;

done:
    pn_scene_free(scene);
    pn_context_free(ctx);
    return code;
}
