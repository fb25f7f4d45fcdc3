/* merge.c — `penumbra merge PARTS... -o FULL.exr [--stats FULL.json]`: crop renders of one image
 * (`--crop`, `--piece K/M`, render-farm regions) assembled into the whole image, bit for bit what
 * one render of the whole window writes (docs/distributed.md).
 *
 * The pixels are assembled by the library (pn_image_merge: same display window and layers, no
 * overlap, full coverage, else exit 3 naming the part). Statistics: every PART.json given among
 * the arguments is a part's `--stats` file; the parts must have been rendered with the same
 * settings (crop, threads and the per-piece options piece and checkpoint aside), and --stats
 * writes one JSON whose `stats` combine them by the rule the library's statistics table declares
 * for each (pn_stat_info.merge: counts and seconds summed, maxima and sizes of the run the
 * maximum, per-pixel means and fractions weighted by each part's pixels, `partial` if any part
 * was, width and height the whole image's). --max-image-pixels N sets the pixel limit every part
 * is read under (the context's, as `info` and `diff` take it). */
#include "cli/cli.h"

#include <cjson/cJSON.h>
#include <stdlib.h>
#include <string.h>

static const char merge_help[] =
    "usage: penumbra merge PART.exr... [PART.json...] -o FULL.exr [--stats FULL.json]\n"
    "\n"
    "Assembles crop renders of one image (--crop, --piece K/M) into the whole image: every layer,\n"
    "bit-identical to a render of the whole window. The parts must share the display window and\n"
    "the layers, must not overlap and must cover the image (exit 3 otherwise). PART.json files are\n"
    "the parts' --stats files; with --stats their statistics are combined into FULL.json.\n"
    "\n"
    "options:\n"
    "  -o, --output FILE      the whole image (.exr)\n"
    "  --stats FILE           combined statistics of the PART.json files\n"
    "  --max-image-pixels N   refuse a part larger than N pixels (default 268435456)\n";

static cJSON *read_json(const char *path) {
    const char *why = NULL;
    FILE *f = cli_open_regular(path, "rb", &why);
    if (!f) return NULL;
    char *text = NULL;
    size_t size = 0, cap = 0, n;
    char buf[65536];
    while ((n = fread(buf, 1, sizeof buf, f)) > 0) {
        if (size + n + 1 > cap) {
            cap = (size + n + 1) * 2;
            char *t = realloc(text, cap);
            if (!t) break;
            text = t;
        }
        memcpy(text + size, buf, n);
        size += n;
    }
    fclose(f);
    if (!text) return NULL;
    text[size] = '\0';
    cJSON *root = cJSON_Parse(text);
    free(text);
    return root;
}

/* The settings that must agree between parts of one image. */
static cJSON *comparable_settings(const cJSON *root) {
    cJSON *set = cJSON_Duplicate(cJSON_GetObjectItemCaseSensitive(root, "settings"), 1);
    if (!set) return NULL;
    cJSON_DeleteItemFromObjectCaseSensitive(set, "crop");
    cJSON_DeleteItemFromObjectCaseSensitive(set, "threads");
    cJSON *opts = cJSON_GetObjectItemCaseSensitive(set, "options");
    cJSON_DeleteItemFromObjectCaseSensitive(opts, "piece");
    cJSON_DeleteItemFromObjectCaseSensitive(opts, "checkpoint");
    return set;
}

/* Combines the `stats` objects of the parts into `out` (rules in the file comment). */
static void combine_stats(cJSON *const *parts, int count, int width, int height, cJSON *out) {
    double total_pixels = 0.0;
    double *pixels = calloc((size_t)count, sizeof *pixels);
    if (!pixels) return;
    for (int i = 0; i < count; i++) {
        const cJSON *s = cJSON_GetObjectItemCaseSensitive(parts[i], "stats");
        const cJSON *w = cJSON_GetObjectItemCaseSensitive(s, "width"),
                    *h = cJSON_GetObjectItemCaseSensitive(s, "height");
        pixels[i] = cJSON_IsNumber(w) && cJSON_IsNumber(h) ? w->valuedouble * h->valuedouble : 0.0;
        total_pixels += pixels[i];
    }
    const cJSON *first = cJSON_GetObjectItemCaseSensitive(parts[0], "stats");
    const cJSON *item;
    cJSON_ArrayForEach(item, first) {
        const char *key = item->string;
        if (cJSON_IsBool(item)) {
            int any = 0;
            for (int i = 0; i < count; i++)
                any |= cJSON_IsTrue(
                    cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(parts[i], "stats"), key));
            cJSON_AddBoolToObject(out, key, any);
            continue;
        }
        if (!cJSON_IsNumber(item)) {
            cJSON_AddItemToObject(out, key, cJSON_Duplicate(item, 1));
            continue;
        }
        /* How the parts combine is declared in the library's statistics table; a statistic it
         * does not know (from another version) is summed. */
        const pn_stat_info *si = pn_stat_get(pn_stat_find(key));
        pn_stat_merge rule = si ? si->merge : PN_STAT_MERGE_SUM;
        double v = 0.0;
        for (int i = 0; i < count; i++) {
            const cJSON *x = cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(parts[i], "stats"), key);
            double d = cJSON_IsNumber(x) ? x->valuedouble : 0.0;
            if (rule == PN_STAT_MERGE_MAX)
                v = i == 0 || d > v ? d : v;
            else if (rule == PN_STAT_MERGE_MEAN)
                v += total_pixels > 0.0 ? d * pixels[i] / total_pixels : 0.0;
            else if (rule == PN_STAT_MERGE_FIRST)
                v = i == 0 ? d : v;
            else
                v += d;
        }
        /* The whole image's size; a work window's scaled from the first part as its own. */
        const cJSON *fw = cJSON_GetObjectItemCaseSensitive(first, "width"),
                    *fh = cJSON_GetObjectItemCaseSensitive(first, "height");
        const cJSON *x0 = cJSON_GetObjectItemCaseSensitive(first, key);
        if (rule == PN_STAT_MERGE_WIDTH)
            v = cJSON_IsNumber(fw) && fw->valuedouble > 0.0 ? x0->valuedouble * width / fw->valuedouble : width;
        if (rule == PN_STAT_MERGE_HEIGHT)
            v = cJSON_IsNumber(fh) && fh->valuedouble > 0.0 ? x0->valuedouble * height / fh->valuedouble : height;
        cJSON_AddNumberToObject(out, key, v);
    }
    free(pixels);
}

static int write_merged_stats(cJSON *const *parts, const char *const *names, int count, const char *image_path,
                              int width, int height, const char *stats_path) {
    cJSON *root = cJSON_Duplicate(parts[0], 1);
    if (!root) return EXIT_SYSTEM;
    cJSON_ReplaceItemInObjectCaseSensitive(root, "image", cJSON_CreateString(image_path));
    cJSON *set = cJSON_GetObjectItemCaseSensitive(root, "settings");
    if (set) cJSON_ReplaceItemInObjectCaseSensitive(set, "crop", cJSON_CreateNull());
    cJSON *stats = cJSON_CreateObject();
    combine_stats(parts, count, width, height, stats);
    cJSON_ReplaceItemInObjectCaseSensitive(root, "stats", stats);
    cJSON_AddItemToObject(root, "merged_from", cJSON_CreateStringArray(names, count));
    char *text = json_print(root);
    cJSON_Delete(root);
    pn_context ctx = pn_context_new();
    pn_status st = text && ctx ? pn_file_write(ctx, stats_path, text, strlen(text)) : PN_ERROR_OUT_OF_MEMORY;
    int code = st == PN_OK ? EXIT_OK : ctx ? report_failure(ctx, st) : EXIT_SYSTEM;
    free(text);
    pn_context_free(ctx);
    return code;
}

int command_merge(int argc, char **argv) {
    const char *output = NULL, *stats_path = NULL;
    const char **images = calloc((size_t)argc, sizeof *images), **jsons = calloc((size_t)argc, sizeof *jsons);
    int image_count = 0, json_count = 0, code = -1;
    uint64_t max_pixels = 0; /* --max-image-pixels; 0 = the default */
    if (!images || !jsons) code = EXIT_SYSTEM;
    arg_scanner s = {"merge", argc, argv, 0, "", NULL, 0};
    const char *positional;
    int kind;
    while (code < 0 && (kind = scanner_next(&s, &positional)) != 0) {
        if (kind == 2) {
            if (ends_with(positional, ".json"))
                jsons[json_count++] = positional;
            else
                images[image_count++] = positional;
        } else if (strcmp(s.name, "-h") == 0 || strcmp(s.name, "--help") == 0) {
            fputs(merge_help, stdout);
            code = EXIT_OK;
        } else if (strcmp(s.name, "-o") == 0 || strcmp(s.name, "--output") == 0) {
            if (!(output = scanner_value(&s))) code = EXIT_USAGE;
        } else if (strcmp(s.name, "--stats") == 0) {
            if (!(stats_path = scanner_value(&s))) code = EXIT_USAGE;
        } else if (strcmp(s.name, "--max-image-pixels") == 0) {
            const char *value = scanner_value(&s);
            if (!value || !parse_pixel_limit("merge", s.name, value, &max_pixels)) code = EXIT_USAGE;
        } else {
            code = usage_error("merge", "unknown option '%s'", s.name);
        }
    }
    if (code < 0 && image_count == 0) code = usage_error("merge", "no part images given");
    if (code < 0 && !output) code = usage_error("merge", "no output image given (-o FULL.exr)");
    if (code < 0 && !ends_with(output, ".exr"))
        code = usage_error("merge", "the output '%s' must be an .exr file", output);
    if (code < 0 && stats_path && json_count == 0)
        code = usage_error("merge", "--stats needs the parts' statistics (PART.json arguments)");
    if (code < 0 && (code = check_output_folder(output)) == EXIT_OK) code = -1;
    if (code >= 0) {
        free(images);
        free(jsons);
        return code;
    }

    pn_context ctx = pn_context_new();
    pn_image *parts = calloc((size_t)image_count, sizeof *parts);
    cJSON **stats = calloc((size_t)(json_count ? json_count : 1), sizeof *stats);
    pn_image full = NULL;
    if (!ctx || !parts || !stats) code = EXIT_SYSTEM;
    if (ctx && max_pixels) pn_context_set_image_pixel_limit(ctx, max_pixels);
    for (int i = 0; code < 0 && i < image_count; i++) {
        pn_status st = pn_image_read_layers(ctx, images[i], &parts[i]);
        if (st != PN_OK) code = report_failure(ctx, st);
    }
    cJSON *reference = NULL;
    for (int i = 0; code < 0 && i < json_count; i++) {
        stats[i] = read_json(jsons[i]);
        if (!stats[i] || !cJSON_IsObject(cJSON_GetObjectItemCaseSensitive(stats[i], "stats"))) {
            fprintf(stderr, "penumbra: %s: not a penumbra statistics JSON\n", jsons[i]);
            code = EXIT_BAD_INPUT;
            break;
        }
        cJSON *cmp = comparable_settings(stats[i]);
        if (i == 0) {
            reference = cmp;
        } else {
            if (!cJSON_Compare(reference, cmp, 1)) {
                fprintf(stderr, "penumbra: %s: rendered with other settings than %s (parts of different renders?)\n",
                        jsons[i], jsons[0]);
                code = EXIT_BAD_INPUT;
            }
            cJSON_Delete(cmp);
        }
    }
    cJSON_Delete(reference);
    if (code < 0) {
        pn_status st = pn_image_merge(ctx, parts, images, image_count, &full);
        if (st == PN_OK) st = pn_image_write(ctx, full, output, 0.0f);
        if (st != PN_OK) code = report_failure(ctx, st);
    }
    if (code < 0 && stats_path)
        code = write_merged_stats(stats, jsons, json_count, output, pn_image_width(full), pn_image_height(full),
                                  stats_path);
    if (code < 0) code = EXIT_OK;
    for (int i = 0; parts && i < image_count; i++) pn_image_free(parts[i]);
    for (int i = 0; stats && i < json_count; i++) cJSON_Delete(stats[i]);
    free(parts);
    free(stats);
    pn_image_free(full);
    pn_context_free(ctx);
    free(images);
    free(jsons);
    return code;
}
