/* illuminance.c — `penumbra illuminance` (calculation grids and point lists, with no camera:
 * CSV, JSON statistics and an isolux picture) and `penumbra falsecolor` (a false-colour picture
 * of an image layer with a legend in real units, after RADIANCE's falsecolor). The grid syntax,
 * the point-file format and the outputs are documented in docs/lighting-design.md.
 *
 * Grid points follow EN 12464-1 / CIE's convention for a rectangular calculation area: the area
 * is divided into nu x nv equal cells no larger than the spacing (n = ceil(length / spacing)),
 * and a point sits at the centre of every cell. U0 = E_min / E_mean. */
#include "cli/cli.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static const char illuminance_help[] =
    "usage: penumbra illuminance SCENE.pbrt (--grid U0,V0,U1,V1 | --points FILE) [options]\n"
    "\n"
    "Computes the illuminance (lux) at calculation points, without a camera: the direct light with\n"
    "--integrator reference (the default), the total light (interreflections through VPLs) with\n"
    "--integrator vpl or lightcuts. Writes one CSV row per point (x,y,z,nx,ny,nz,illuminance_lux),\n"
    "a JSON file with E_min, E_mean, E_max, U0 = E_min / E_mean and the points, and for a grid an\n"
    "isolux picture (PNG) of the plane.\n"
    "\n"
    "points:\n"
    "  --grid U0,V0,U1,V1     a rectangular work plane: corners (U0,V0) and (U1,V1) in the two\n"
    "                         horizontal axes (x,y for --up z; x,z for --up y; y,z for --up x); its\n"
    "                         cells no larger than --spacing, a point at the centre of each\n"
    "  --height H             the plane's height along the up axis (default 0.75)\n"
    "  --spacing S            largest cell side (default 0.5)\n"
    "  --up x|y|z             the up axis and the points' normal (+; default z)\n"
    "  --points FILE          one point per line, 'x y z nx ny nz' (as RADIANCE rtrace -I reads);\n"
    "                         blank lines and lines starting with # are skipped\n"
    "\n"
    "outputs:\n"
    "  -o FILE.csv            the CSV (default illuminance.csv)\n"
    "  --json FILE            the statistics (default: the CSV's name with .json)\n"
    "  --png FILE             the isolux picture of a grid (default: the CSV's name with .png)\n"
    "  --png-style S          bands (default), lines or smooth\n"
    "  --daylight-factor E    also the daylight factor, 100 x E_point / E (E: the unobstructed\n"
    "                         horizontal illuminance of the scene's sky, in lux)\n"
    "  --melanopic            also the melanopic EDI (CIE S 026 melanopic equivalent daylight (D65)\n"
    "                         illuminance, lux): a CSV column melanopic_edi_lux and its statistics;\n"
    "                         needs --spectral and --integrator reference\n"
    "\n"
    "Every option of 'penumbra render' that selects and tunes the integrator applies: --integrator,\n"
    "--spp (samples per point, default 64), --seed, --threads, --shadow-rays, --vpls, ... The result\n"
    "does not depend on --threads.\n";

static const char falsecolor_help[] =
    "usage: penumbra falsecolor IN.exr [--layer NAME] -o OUT.png [options]\n"
    "\n"
    "A false-colour picture of one single-channel layer of IN (default: luminance) with a legend in\n"
    "its units, after RADIANCE's falsecolor: dark purple (low) through blue, green, red to yellow.\n"
    "\n"
    "options (RADIANCE's names):\n"
    "  -s SCALE | -s auto     top of the scale (default 1000; auto: the layer's maximum)\n"
    "  -m MULT                multiply the layer's values first (default 1: the layers are in lux\n"
    "                         and cd/m2 already)\n"
    "  -log DECADES           logarithmic, DECADES decades below the scale (default linear from 0)\n"
    "  -n DIVISIONS           legend boxes and contour levels (default 8)\n"
    "  -cl | -cb              contour lines on black, or bands (default continuous)\n"
    "  -l LABEL               legend label (default lux for illuminance, cd/m2 for luminance)\n";

/* ---- the points ------------------------------------------------------------------------------ */

typedef struct grid_spec {
    int has;
    double u0, v0, u1, v1, height, spacing;
    int up;     /* 0 x, 1 y, 2 z */
    int nu, nv; /* cells */
} grid_spec;

/* The world axes of the grid's (u, v) for each up axis. */
static void grid_axes(int up, int *au, int *av) {
    static const int u_axis[3] = {1, 0, 0}, v_axis[3] = {2, 2, 1};
    *au = u_axis[up];
    *av = v_axis[up];
}

static pn_illuminance_point *grid_points(grid_spec *g, int *count) {
    double lu = fabs(g->u1 - g->u0), lv = fabs(g->v1 - g->v0);
    g->nu = (int)ceil(lu / g->spacing - 1e-9);
    g->nv = (int)ceil(lv / g->spacing - 1e-9);
    if (g->nu < 1) g->nu = 1;
    if (g->nv < 1) g->nv = 1;
    if ((long)g->nu * g->nv > 4000000L) return NULL;
    pn_illuminance_point *pts = calloc((size_t)g->nu * (size_t)g->nv, sizeof *pts);
    if (!pts) return NULL;
    int au, av;
    grid_axes(g->up, &au, &av);
    double umin = fmin(g->u0, g->u1), vmin = fmin(g->v0, g->v1);
    for (int j = 0; j < g->nv; j++)
        for (int i = 0; i < g->nu; i++) {
            pn_illuminance_point *p = &pts[(size_t)j * (size_t)g->nu + (size_t)i];
            p->p[au] = (float)(umin + ((double)i + 0.5) * lu / (double)g->nu);
            p->p[av] = (float)(vmin + ((double)j + 0.5) * lv / (double)g->nv);
            p->p[g->up] = (float)g->height;
            p->n[g->up] = 1.0f;
        }
    *count = g->nu * g->nv;
    return pts;
}

/* Reads one line of at most size - 1 bytes (through its '\n' when it fits) into line, NUL bytes
 * included, and its length into *len (fgets cannot say where a NUL byte ends what it read).
 * Returns 0 at the end of the file with nothing read. */
static int read_points_line(FILE *f, char *line, size_t size, size_t *len) {
    size_t n = 0;
    int c = 0;
    while (n + 1 < size && (c = getc(f)) != EOF) {
        line[n++] = (char)c;
        if (c == '\n') break;
    }
    line[n] = '\0';
    *len = n;
    return n > 0;
}

/* Reads a point file; on a bad line prints "file:line:column: message" and returns NULL with
 * *code = EXIT_BAD_INPUT (EXIT_SYSTEM when unreadable). */
static pn_illuminance_point *read_points(const char *path, int *count, int *code) {
    *count = 0;
    const char *why = NULL;
    errno = 0;
    FILE *f = cli_open_regular(path, "r", &why);
    if (!f) {
        fprintf(stderr, "penumbra illuminance: %s: %s\n", path, why);
        *code = errno == ENOENT || errno == EINVAL ? EXIT_BAD_INPUT : EXIT_SYSTEM;
        return NULL;
    }
    pn_illuminance_point *pts = NULL;
    int n = 0, cap = 0, line_no = 0;
    char line[4096];
    *code = EXIT_BAD_INPUT;
    size_t len = 0;
    while (read_points_line(f, line, sizeof line, &len)) {
        if (line_no == INT_MAX) {
            fprintf(stderr, "%s:%d:1: more than %d lines\n", path, line_no, INT_MAX);
            goto fail;
        }
        line_no++;
        if (len == sizeof line - 1 && line[len - 1] != '\n' && !feof(f)) {
            fprintf(stderr, "%s:%d:1: line longer than %d characters\n", path, line_no, (int)sizeof line - 2);
            goto fail;
        }
        /* A NUL byte would end the line early and hide what follows: not a text file. */
        const char *nul = memchr(line, '\0', len);
        if (nul) {
            fprintf(stderr, "%s:%d:%d: a NUL byte: not a text file\n", path, line_no, (int)(nul - line) + 1);
            goto fail;
        }
        const char *c = line;
        while (*c == ' ' || *c == '\t' || *c == '\r' || *c == '\n') c++;
        if (*c == '\0' || *c == '#') continue;
        double v[6];
        int k = 0;
        for (;;) {
            while (*c == ' ' || *c == '\t' || *c == '\r' || *c == '\n') c++;
            if (*c == '\0') break;
            int column = (int)(c - line) + 1;
            if (k == 6) {
                fprintf(stderr, "%s:%d:%d: more than 6 numbers (x y z nx ny nz)\n", path, line_no, column);
                goto fail;
            }
            char *end;
            errno = 0;
            double x = strtod(c, &end);
            if (end == c || (*end && *end != ' ' && *end != '\t' && *end != '\r' && *end != '\n')) {
                const char *e = c;
                while (*e && *e != ' ' && *e != '\t' && *e != '\r' && *e != '\n') e++;
                fprintf(stderr, "%s:%d:%d: '%.*s' is not a number\n", path, line_no, column, (int)(e - c), c);
                goto fail;
            }
            if (!isfinite(x) || errno == ERANGE || fabs(x) > 1e30) {
                fprintf(stderr, "%s:%d:%d: %.*s is not a finite coordinate\n", path, line_no, column, (int)(end - c),
                        c);
                goto fail;
            }
            v[k++] = x;
            c = end;
        }
        if (k < 6) {
            fprintf(stderr, "%s:%d:%d: expected 6 numbers (x y z nx ny nz), found %d\n", path, line_no,
                    (int)(c - line) + 1 - (c > line && c[-1] == '\n'), k);
            goto fail;
        }
        if (!(v[3] * v[3] + v[4] * v[4] + v[5] * v[5] > 0.0)) {
            fprintf(stderr, "%s:%d:1: the normal (%g %g %g) has zero length\n", path, line_no, v[3], v[4], v[5]);
            goto fail;
        }
        if (n == cap) {
            if (cap >= 4000000) {
                fprintf(stderr, "%s:%d:1: more than 4000000 points\n", path, line_no);
                goto fail;
            }
            cap = cap ? 2 * cap : 256;
            pn_illuminance_point *np = realloc(pts, (size_t)cap * sizeof *np);
            if (!np) {
                fprintf(stderr, "penumbra illuminance: out of memory\n");
                *code = EXIT_SYSTEM;
                goto fail;
            }
            pts = np;
        }
        for (int q = 0; q < 3; q++) {
            pts[n].p[q] = (float)v[q];
            pts[n].n[q] = (float)v[3 + q];
        }
        n++;
    }
    if (ferror(f)) {
        fprintf(stderr, "penumbra illuminance: %s: read error\n", path);
        *code = EXIT_SYSTEM;
        goto fail;
    }
    if (n == 0) {
        fprintf(stderr, "%s:%d:1: no points (one per line: x y z nx ny nz)\n", path, line_no > 0 ? line_no : 1);
        goto fail;
    }
    fclose(f);
    *count = n;
    *code = EXIT_OK;
    return pts;
fail:
    fclose(f);
    free(pts);
    return NULL;
}

/* ---- outputs ----------------------------------------------------------------------------------- */

typedef struct grid_stats {
    double min, mean, max, u0;
} grid_stats;

static grid_stats stats_of(const double *v, int n, double factor) {
    grid_stats s = {INFINITY, 0.0, -INFINITY, 0.0};
    for (int i = 0; i < n; i++) {
        double x = v[i] * factor;
        s.min = fmin(s.min, x);
        s.max = fmax(s.max, x);
        s.mean += x;
    }
    s.mean /= (double)n;
    s.u0 = s.mean > 0.0 ? s.min / s.mean : 0.0;
    return s;
}

static char *replace_extension(const char *path, const char *ext) {
    const char *dot = strrchr(path, '.'), *slash = strrchr(path, '/');
    size_t stem = dot && (!slash || dot > slash) ? (size_t)(dot - path) : strlen(path);
    char *out = malloc(stem + strlen(ext) + 1);
    if (!out) return NULL;
    memcpy(out, path, stem);
    strcpy(out + stem, ext);
    return out;
}

static int write_csv(pn_context ctx, pn_output_set set, const char *path, const pn_illuminance_point *pts,
                     const double *lux, const double *edi, int n, double df_reference) {
    size_t cap = (size_t)n * 180 + 160, len = 0;
    char *buf = malloc(cap);
    if (!buf) return EXIT_SYSTEM;
    len += (size_t)snprintf(buf + len, cap - len, "x,y,z,nx,ny,nz,illuminance_lux%s%s\n",
                            df_reference > 0.0 ? ",daylight_factor_percent" : "", edi ? ",melanopic_edi_lux" : "");
    for (int i = 0; i < n; i++) {
        const pn_illuminance_point *p = &pts[i];
        len += (size_t)snprintf(buf + len, cap - len, "%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g", (double)p->p[0],
                                (double)p->p[1], (double)p->p[2], (double)p->n[0], (double)p->n[1], (double)p->n[2],
                                lux[i]);
        if (df_reference > 0.0) len += (size_t)snprintf(buf + len, cap - len, ",%.9g", 100.0 * lux[i] / df_reference);
        if (edi) len += (size_t)snprintf(buf + len, cap - len, ",%.9g", edi[i]);
        len += (size_t)snprintf(buf + len, cap - len, "\n");
    }
    pn_status st = pn_output_set_add_file(ctx, set, path, buf, len);
    free(buf);
    return st == PN_OK ? EXIT_OK : report_failure(ctx, st);
}

/* "direct" or "total": what the method table says the integrator computes (VPL global
 * illumination or direct light). */
static const char *quantity_of(const char *integrator, pn_options options) {
    int m = pn_method_find(PN_METHOD_INTEGRATOR, integrator);
    const pn_method_info *mi = m >= 0 ? pn_method_get(m) : NULL;
    double direct_only = 0.0;
    int opt = pn_option_find("vpl-direct-only");
    if (opt >= 0) pn_options_get(options, opt, &direct_only, NULL, 0);
    return mi && strncmp(mi->computes, "global", 6) == 0 && direct_only == 0.0 ? "total" : "direct";
}

static void add_stats(cJSON *root, const char *prefix, grid_stats s) {
    char name[64];
    snprintf(name, sizeof name, "%s_min", prefix);
    cJSON_AddNumberToObject(root, name, s.min);
    snprintf(name, sizeof name, "%s_mean", prefix);
    cJSON_AddNumberToObject(root, name, s.mean);
    snprintf(name, sizeof name, "%s_max", prefix);
    cJSON_AddNumberToObject(root, name, s.max);
}

static int write_json(pn_context ctx, pn_output_set set, const char *path, const char *scene, const char *integrator,
                      pn_options options, const grid_spec *g, const pn_illuminance_point *pts, const double *lux,
                      const double *edi, int n, double df_reference, double seconds) {
    cJSON *root = cJSON_CreateObject();
    if (!root) return EXIT_SYSTEM;
    cJSON_AddStringToObject(root, "scene", scene);
    cJSON_AddStringToObject(root, "integrator", integrator);
    cJSON_AddStringToObject(root, "quantity", quantity_of(integrator, options));
    cJSON_AddNumberToObject(root, "points", n);
    grid_stats s = stats_of(lux, n, 1.0);
    add_stats(root, "E", s);
    cJSON_AddNumberToObject(root, "U0", s.u0);
    cJSON_AddNumberToObject(root, "seconds", seconds);
    if (df_reference > 0.0) {
        cJSON_AddNumberToObject(root, "unobstructed_illuminance_lux", df_reference);
        add_stats(root, "DF", stats_of(lux, n, 100.0 / df_reference));
    }
    if (edi) add_stats(root, "EDI_mel", stats_of(edi, n, 1.0));
    if (g->has) {
        static const char *axes = "xyz";
        int au, av;
        grid_axes(g->up, &au, &av);
        cJSON *grid = cJSON_AddObjectToObject(root, "grid");
        char up[2] = {axes[g->up], 0}, u[2] = {axes[au], 0}, v[2] = {axes[av], 0};
        cJSON_AddStringToObject(grid, "up", up);
        cJSON_AddStringToObject(grid, "u_axis", u);
        cJSON_AddStringToObject(grid, "v_axis", v);
        double corners[4] = {fmin(g->u0, g->u1), fmin(g->v0, g->v1), fmax(g->u0, g->u1), fmax(g->v0, g->v1)};
        cJSON_AddItemToObject(grid, "corners_uv", cJSON_CreateDoubleArray(corners, 4));
        cJSON_AddNumberToObject(grid, "height", g->height);
        cJSON_AddNumberToObject(grid, "spacing", g->spacing);
        cJSON_AddNumberToObject(grid, "nu", g->nu);
        cJSON_AddNumberToObject(grid, "nv", g->nv);
        cJSON_AddNumberToObject(grid, "cell_u", (corners[2] - corners[0]) / g->nu);
        cJSON_AddNumberToObject(grid, "cell_v", (corners[3] - corners[1]) / g->nv);
    }
    cJSON *coords = cJSON_AddArrayToObject(root, "coordinates");
    cJSON *values = cJSON_AddArrayToObject(root, "illuminance_lux");
    for (int i = 0; i < n; i++) {
        double p[3] = {pts[i].p[0], pts[i].p[1], pts[i].p[2]};
        cJSON_AddItemToArray(coords, cJSON_CreateDoubleArray(p, 3));
        cJSON_AddItemToArray(values, cJSON_CreateNumber(lux[i]));
    }
    if (edi) {
        cJSON *mel = cJSON_AddArrayToObject(root, "melanopic_edi_lux");
        for (int i = 0; i < n; i++) cJSON_AddItemToArray(mel, cJSON_CreateNumber(edi[i]));
    }
    char *text = json_print(root);
    cJSON_Delete(root);
    if (!text) return EXIT_SYSTEM;
    pn_status st = pn_output_set_add_file(ctx, set, path, text, strlen(text));
    free(text);
    return st == PN_OK ? EXIT_OK : report_failure(ctx, st);
}

/* The isolux picture: the grid's values bilinearly interpolated between the cell centres onto a
 * picture of at least 256 pixels along its longer side, top row at the largest v. */
static int write_isolux(pn_context ctx, pn_output_set set, const char *path, const grid_spec *g, const double *lux,
                        double factor, pn_false_color_style style, const char *label) {
    int px_per_cell = (int)ceil(256.0 / (double)(g->nu > g->nv ? g->nu : g->nv));
    if (px_per_cell < 1) px_per_cell = 1;
    int w = g->nu * px_per_cell, h = g->nv * px_per_cell;
    float *img = malloc((size_t)w * (size_t)h * sizeof *img);
    if (!img) return EXIT_SYSTEM;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double fu = ((double)x + 0.5) / px_per_cell - 0.5, fv = (double)(h - 1 - y) + 0.5;
            fv = fv / px_per_cell - 0.5;
            fu = fmin(fmax(fu, 0.0), (double)(g->nu - 1));
            fv = fmin(fmax(fv, 0.0), (double)(g->nv - 1));
            int i0 = (int)fu, j0 = (int)fv;
            int i1 = i0 + 1 < g->nu ? i0 + 1 : i0, j1 = j0 + 1 < g->nv ? j0 + 1 : j0;
            double a = fu - i0, b = fv - j0;
            double v00 = lux[(size_t)j0 * g->nu + i0], v10 = lux[(size_t)j0 * g->nu + i1];
            double v01 = lux[(size_t)j1 * g->nu + i0], v11 = lux[(size_t)j1 * g->nu + i1];
            double v = (1 - b) * ((1 - a) * v00 + a * v10) + b * ((1 - a) * v01 + a * v11);
            img[(size_t)y * w + x] = (float)(v * factor);
        }
    pn_image values = NULL, picture = NULL;
    pn_status st = pn_image_from_values(ctx, w, h, "illuminance", img, &values);
    free(img);
    pn_false_color_options fo = {0.0, 1.0, 0, 8, style, label};
    if (st == PN_OK) st = pn_image_false_color_legend(ctx, values, "illuminance", &fo, &picture);
    if (st == PN_OK) st = pn_output_set_add_image(ctx, set, picture, path, 0.0f);
    pn_image_free(values);
    pn_image_free(picture);
    return st == PN_OK ? EXIT_OK : report_failure(ctx, st);
}

static int parse_list(const char *text, double *v, int n) {
    const char *c = text;
    for (int i = 0; i < n; i++) {
        char *end;
        errno = 0;
        v[i] = strtod(c, &end);
        if (end == c || errno == ERANGE || !isfinite(v[i])) return 0;
        c = end;
        if (i + 1 < n) {
            if (*c != ',') return 0;
            c++;
        }
    }
    return *c == '\0';
}

int command_illuminance(int argc, char **argv) {
    const char *cmd = "illuminance";
    grid_spec g = {0, 0, 0, 0, 0, 0.75, 0.5, 2, 0, 0};
    const char *points_path = NULL, *csv_path = "illuminance.csv", *json_path = NULL, *png_path = NULL;
    double df_reference = 0.0;
    int melanopic = 0;
    pn_false_color_style style = PN_FALSE_COLOR_BANDS;
    /* Our options are taken out; the rest (scene, integrator and its options) go to render's parser. */
    char **rest = calloc((size_t)argc + 2, sizeof *rest);
    if (!rest) return EXIT_SYSTEM;
    int nrest = 0;
    rest[nrest++] = "illuminance";
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
        int takes = strcmp(a, "--grid") == 0 || strcmp(a, "--height") == 0 || strcmp(a, "--spacing") == 0 ||
                    strcmp(a, "--up") == 0 || strcmp(a, "--points") == 0 || strcmp(a, "-o") == 0 ||
                    strcmp(a, "--output") == 0 || strcmp(a, "--json") == 0 || strcmp(a, "--png") == 0 ||
                    strcmp(a, "--png-style") == 0 || strcmp(a, "--daylight-factor") == 0;
        if (strcmp(a, "-h") == 0 || strcmp(a, "--help") == 0) {
            fputs(illuminance_help, stdout);
            free(rest);
            return EXIT_OK;
        }
        if (strcmp(a, "--melanopic") == 0) {
            melanopic = 1;
            continue;
        }
        if (!takes) {
            rest[nrest++] = argv[i];
            continue;
        }
        if (!v) {
            free(rest);
            return usage_error(cmd, "option '%s' needs a value", a);
        }
        i++;
        int ok = 1;
        if (strcmp(a, "--grid") == 0) {
            double c[4];
            ok = parse_list(v, c, 4) && c[0] != c[2] && c[1] != c[3];
            g.u0 = c[0], g.v0 = c[1], g.u1 = c[2], g.v1 = c[3], g.has = 1;
            if (!ok) {
                free(rest);
                return bad_value(cmd, a, v, "four numbers U0,V0,U1,V1 with U0 != U1 and V0 != V1");
            }
        } else if (strcmp(a, "--height") == 0) {
            ok = parse_double(v, &g.height) && isfinite(g.height);
        } else if (strcmp(a, "--spacing") == 0) {
            ok = parse_double(v, &g.spacing) && g.spacing > 0.0 && isfinite(g.spacing);
        } else if (strcmp(a, "--up") == 0) {
            ok = (v[0] == 'x' || v[0] == 'y' || v[0] == 'z') && v[1] == '\0';
            if (ok) g.up = v[0] - 'x';
        } else if (strcmp(a, "--points") == 0) {
            points_path = v;
        } else if (strcmp(a, "-o") == 0 || strcmp(a, "--output") == 0) {
            ok = ends_with(v, ".csv");
        } else if (strcmp(a, "--json") == 0) {
            json_path = v;
            ok = ends_with(v, ".json");
        } else if (strcmp(a, "--png") == 0) {
            png_path = v;
            ok = ends_with(v, ".png");
        } else if (strcmp(a, "--png-style") == 0) {
            ok = strcmp(v, "bands") == 0 || strcmp(v, "lines") == 0 || strcmp(v, "smooth") == 0;
            style = v[0] == 'b' ? PN_FALSE_COLOR_BANDS : v[0] == 'l' ? PN_FALSE_COLOR_LINES : PN_FALSE_COLOR_SMOOTH;
        } else if (strcmp(a, "--daylight-factor") == 0) {
            ok = parse_double(v, &df_reference) && df_reference > 0.0 && isfinite(df_reference);
        }
        if (strcmp(a, "-o") == 0 || strcmp(a, "--output") == 0) csv_path = v;
        if (!ok) {
            free(rest);
            return bad_value(cmd, a, v, "see 'penumbra illuminance --help'");
        }
    }
    if (g.has == (points_path != NULL)) {
        free(rest);
        return usage_error(cmd, "give exactly one of --grid and --points");
    }
    render_options o;
    memset(&o, 0, sizeof o);
    o.options = pn_options_new();
    if (!o.options) {
        free(rest);
        return EXIT_SYSTEM;
    }
    int code = parse_render_args(nrest, rest, &o);
    free(rest);
    if (code >= 0) {
        pn_options_free(o.options);
        return code;
    }
    code = EXIT_OK;
    if (!o.scene_path) {
        pn_options_free(o.options);
        return usage_error(cmd, "no scene file given");
    }
    if (melanopic) {
        double spectral = 0.0;
        int si = pn_option_find("spectral");
        if (si >= 0 && pn_options_is_set(o.options, si)) pn_options_get(o.options, si, &spectral, NULL, 0);
        /* The integrator is checked by pn_illuminance_melanopic (reference, vpl, lightcuts). */
        const char *why = spectral == 0.0 ? "needs --spectral (the melanopic EDI is integrated from the light's "
                                            "spectrum at sampled wavelengths, which RGB mode does not carry)"
                                          : NULL;
        if (why) {
            pn_options_free(o.options);
            return usage_error(cmd, "--melanopic %s", why);
        }
    }
    char *json_default = json_path ? NULL : replace_extension(csv_path, ".json");
    char *png_default = png_path ? NULL : replace_extension(csv_path, ".png");
    if (!json_path) json_path = json_default;
    if (!png_path) png_path = png_default;
    pn_illuminance_point *pts = NULL;
    double *lux = NULL, *edi = NULL;
    int n = 0;
    pn_context ctx = NULL;
    pn_scene scene = NULL;
    if (!json_path || !png_path) {
        code = EXIT_SYSTEM;
        goto done;
    }
    if (points_path) {
        pts = read_points(points_path, &n, &code);
        if (!pts) goto done;
    } else {
        pts = grid_points(&g, &n);
        if (!pts) {
            code = usage_error(cmd, "the grid has too many points (at most 4000000)");
            goto done;
        }
    }
    lux = calloc((size_t)n, sizeof *lux);
    edi = melanopic ? calloc((size_t)n, sizeof *edi) : NULL;
    ctx = pn_context_new();
    if (!lux || !ctx || (melanopic && !edi)) {
        code = EXIT_SYSTEM;
        goto done;
    }
    log_options log = {o.quiet, 1};
    pn_context_set_log(ctx, on_log, &log);
    pn_status st = pn_scene_load(ctx, o.scene_path, &scene);
    if (st != PN_OK) {
        code = report_failure(ctx, st);
        goto done;
    }
    double t0 = monotonic_seconds();
    st = pn_illuminance_melanopic(ctx, scene, &o.settings, pts, n, lux, edi);
    double seconds = monotonic_seconds() - t0;
    if (st != PN_OK) {
        code = report_failure(ctx, st);
        goto done;
    }
    const char *integrator = pn_method_get(o.integrator)->name;
    /* The CSV, JSON and isolux picture are written as one set: all of them or none. */
    pn_output_set set = pn_output_set_new();
    if (!set) {
        code = EXIT_SYSTEM;
        goto done;
    }
    code = write_csv(ctx, set, csv_path, pts, lux, edi, n, df_reference);
    if (code == EXIT_OK)
        code = write_json(ctx, set, json_path, o.scene_path, integrator, o.options, &g, pts, lux, edi, n, df_reference,
                          seconds);
    if (code == EXIT_OK && g.has)
        code = write_isolux(ctx, set, png_path, &g, lux, df_reference > 0.0 ? 100.0 / df_reference : 1.0, style,
                            df_reference > 0.0 ? "DF %" : "lux");
    if (code == EXIT_OK && (st = pn_output_set_commit(ctx, set)) != PN_OK) code = report_failure(ctx, st);
    pn_output_set_free(set);
    if (code != EXIT_OK) goto done;
    if (!o.quiet) {
        grid_stats s = stats_of(lux, n, 1.0);
        printf("%d points (%s, %s light) in %.3f s: E_min %.6g lx, E_mean %.6g lx, E_max %.6g lx, U0 %.4f\n", n,
               integrator, quantity_of(integrator, o.options), seconds, s.min, s.mean, s.max, s.u0);
        if (df_reference > 0.0) {
            grid_stats d = stats_of(lux, n, 100.0 / df_reference);
            printf("daylight factor: min %.4g%%, mean %.4g%%, max %.4g%%\n", d.min, d.mean, d.max);
        }
        if (edi) {
            grid_stats m = stats_of(edi, n, 1.0);
            printf("melanopic EDI: min %.6g lx, mean %.6g lx, max %.6g lx\n", m.min, m.mean, m.max);
        }
        printf("wrote %s, %s%s%s\n", csv_path, json_path, g.has ? ", " : "", g.has ? png_path : "");
    }
done:
    pn_scene_free(scene);
    pn_context_free(ctx);
    free(pts);
    free(lux);
    free(edi);
    free(json_default);
    free(png_default);
    pn_options_free(o.options);
    return code;
}

/* ---- falsecolor ------------------------------------------------------------------------------ */

int command_falsecolor(int argc, char **argv) {
    const char *cmd = "falsecolor";
    const char *in = NULL, *out = NULL, *layer = "luminance", *label = NULL;
    pn_false_color_options fo = {1000.0, 1.0, 0, 8, PN_FALSE_COLOR_SMOOTH, NULL};
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (strcmp(a, "-h") == 0 || strcmp(a, "--help") == 0) {
            fputs(falsecolor_help, stdout);
            return EXIT_OK;
        }
        if (strcmp(a, "-cl") == 0 || strcmp(a, "-cb") == 0) {
            fo.style = a[2] == 'l' ? PN_FALSE_COLOR_LINES : PN_FALSE_COLOR_BANDS;
            continue;
        }
        if (a[0] != '-' || a[1] == '\0') {
            if (in) return usage_error(cmd, "unexpected argument '%s'", a);
            in = a;
            continue;
        }
        if (i + 1 >= argc) return usage_error(cmd, "option '%s' needs a value", a);
        const char *v = argv[++i];
        long k;
        if (strcmp(a, "-o") == 0 || strcmp(a, "--output") == 0) {
            if (!ends_with(v, ".png")) return bad_value(cmd, a, v, "a file name ending in .png");
            out = v;
        } else if (strcmp(a, "--layer") == 0) {
            layer = v;
        } else if (strcmp(a, "-s") == 0) {
            if (v[0] == 'a')
                fo.scale = 0.0;
            else if (!parse_double(v, &fo.scale) || !(fo.scale > 0.0) || !isfinite(fo.scale))
                return bad_value(cmd, a, v, "a positive number or 'auto'");
        } else if (strcmp(a, "-m") == 0) {
            if (!parse_double(v, &fo.multiplier) || !(fo.multiplier > 0.0) || !isfinite(fo.multiplier))
                return bad_value(cmd, a, v, "a positive number");
        } else if (strcmp(a, "-log") == 0) {
            if (!parse_long(v, 1, 20, &k)) return bad_value(cmd, a, v, "an integer from 1 to 20");
            fo.log_decades = (int)k;
        } else if (strcmp(a, "-n") == 0) {
            if (!parse_long(v, 1, 64, &k)) return bad_value(cmd, a, v, "an integer from 1 to 64");
            fo.divisions = (int)k;
        } else if (strcmp(a, "-l") == 0) {
            label = v;
        } else {
            return usage_error(cmd, "unknown option '%s'", a);
        }
    }
    if (!in) return usage_error(cmd, "no input image given");
    if (!out) return usage_error(cmd, "no output given (-o OUT.png)");
    if (!label) label = strcmp(layer, "illuminance") == 0 ? "lux" : strcmp(layer, "luminance") == 0 ? "cd/m2" : "";
    fo.label = label;
    pn_context ctx = pn_context_new();
    if (!ctx) return EXIT_SYSTEM;
    pn_image image = NULL, picture = NULL;
    pn_status st = pn_image_read_layer(ctx, in, layer, &image);
    if (st == PN_OK) st = pn_image_false_color_legend(ctx, image, layer, &fo, &picture);
    if (st == PN_OK) st = pn_image_write(ctx, picture, out, 0.0f);
    int code = st == PN_OK ? EXIT_OK : report_failure(ctx, st);
    pn_image_free(image);
    pn_image_free(picture);
    pn_context_free(ctx);
    return code;
}
