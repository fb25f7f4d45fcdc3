/* pfm.c — Portable Float Map reading and writing.
 *
 * A PFM file is a text header ("PF" for RGB or "Pf" for greyscale, then width, height and a
 * scale whose sign gives the byte order: negative = little endian, positive = big endian)
 * followed by raw 32-bit floats, rows stored from the bottom of the image to the top. As pbrt
 * does, a scale magnitude other than 1 multiplies the values on reading. Writing always uses
 * "PF", little endian, scale -1.
 */
#include "io/image.h"

#include <ctype.h>
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

/* Largest width or height accepted from a header, to refuse absurd allocations early. */
#define PN_PFM_MAX_DIMENSION (1 << 20)

static int pn_host_is_little_endian(void) {
    const uint32_t one = 1;
    unsigned char first;
    memcpy(&first, &one, 1);
    return first == 1;
}

static void pn_swap_floats(float *values, size_t count) {
    for (size_t i = 0; i < count; i++) {
        unsigned char b[4], s[4];
        memcpy(b, &values[i], 4);
        s[0] = b[3];
        s[1] = b[2];
        s[2] = b[1];
        s[3] = b[0];
        memcpy(&values[i], s, 4);
    }
}

/* Reads one whitespace-delimited header token into `buf`; consumes exactly one whitespace
 * character after it (the PFM header ends with a single whitespace before the data). Returns 0
 * on end of file or an over-long token. */
static int pn_pfm_token(FILE *file, char *buf, size_t size) {
    int c;
    do {
        c = fgetc(file);
    } while (c != EOF && isspace(c));
    if (c == EOF) return 0;
    size_t n = 0;
    while (c != EOF && !isspace(c)) {
        if (n + 1 >= size) return 0;
        buf[n++] = (char)c;
        c = fgetc(file);
    }
    buf[n] = '\0';
    return 1;
}

static int pn_parse_dimension(const char *text, int *out) {
    char *end = NULL;
    errno = 0;
    long v = strtol(text, &end, 10);
    if (errno != 0 || end == text || *end != '\0' || v <= 0 || v > PN_PFM_MAX_DIMENSION) return 0;
    *out = (int)v;
    return 1;
}

pn_status pn_pfm_read(FILE *file, const char *name, const pn_image_limits *limits, pn_image *out, pn_err *err) {
    *out = NULL;
    char magic[8], wtext[32], htext[32], stext[64];
    if (!pn_pfm_token(file, magic, sizeof magic) || !pn_pfm_token(file, wtext, sizeof wtext) ||
        !pn_pfm_token(file, htext, sizeof htext) || !pn_pfm_token(file, stext, sizeof stext)) {
        return pn_err_set(err, PN_ERROR_BAD_INPUT, "%s: not a valid PFM file: truncated header", name);
    }
    int channels;
    if (strcmp(magic, "PF") == 0) {
        channels = 3;
    } else if (strcmp(magic, "Pf") == 0) {
        channels = 1;
    } else {
        return pn_err_set(err, PN_ERROR_BAD_INPUT, "%s: not a valid PFM file: header does not start with PF or Pf",
                          name);
    }
    int width, height;
    if (!pn_parse_dimension(wtext, &width) || !pn_parse_dimension(htext, &height)) {
        return pn_err_set(err, PN_ERROR_BAD_INPUT, "%s: not a valid PFM file: bad size '%s x %s'", name, wtext, htext);
    }
    char *end = NULL;
    double scale = strtod(stext, &end);
    if (end == stext || *end != '\0' || !isfinite(scale) || scale == 0.0) {
        return pn_err_set(err, PN_ERROR_BAD_INPUT, "%s: not a valid PFM file: bad scale '%s'", name, stext);
    }

    pn_status limit_status = pn_image_check_size(name, "PFM", width, height, limits, 0, err);
    if (limit_status != PN_OK) return limit_status;
    size_t row_values = (size_t)width * (size_t)channels;
    size_t total_bytes = row_values * (size_t)height * sizeof(float);

    /* Compare with the bytes left in the file before allocating anything large. */
    struct stat st;
    long pos = ftell(file);
    if (pos >= 0 && fstat(fileno(file), &st) == 0 && S_ISREG(st.st_mode)) {
        uint64_t left = (uint64_t)st.st_size > (uint64_t)pos ? (uint64_t)st.st_size - (uint64_t)pos : 0;
        if (left < total_bytes) {
            return pn_err_set(err, PN_ERROR_BAD_INPUT,
                              "%s: not a valid PFM file: truncated pixel data (%llu of %llu bytes)", name,
                              (unsigned long long)left, (unsigned long long)total_bytes);
        }
    }

    pn_image image = pn_image_create(width, height);
    float *row = malloc(row_values * sizeof(float));
    if (!image || !row) {
        pn_image_free(image);
        free(row);
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory for %dx%d image", name, width, height);
    }

    int swap = (scale < 0.0) != pn_host_is_little_endian();
    float factor = (float)fabs(scale);
    float *rgb = image->layers[0].data;
    for (int file_row = 0; file_row < height; file_row++) {
        if (fread(row, sizeof(float), row_values, file) != row_values) {
            int io_error = ferror(file);
            free(row);
            pn_image_free(image);
            if (io_error) return pn_err_set(err, PN_ERROR_IO, "%s: read error", name);
            return pn_err_set(err, PN_ERROR_BAD_INPUT, "%s: not a valid PFM file: truncated pixel data", name);
        }
        if (swap) pn_swap_floats(row, row_values);
        /* File rows go from the bottom of the image to the top. */
        float *dst = rgb + (size_t)(height - 1 - file_row) * (size_t)width * 3;
        for (int x = 0; x < width; x++) {
            for (int c = 0; c < 3; c++) {
                float v = row[(size_t)x * (size_t)channels + (size_t)(channels == 3 ? c : 0)];
                dst[(size_t)x * 3 + (size_t)c] = factor != 1.0f ? v * factor : v;
            }
        }
    }
    free(row);
    *out = image;
    return PN_OK;
}

pn_status pn_pfm_write(pn_image image, FILE *file, const char *name, pn_err *err) {
    const int width = image->width, height = image->height;
    const float *rgb = image->layers[0].data;
    const size_t row_values = (size_t)width * 3;

    /* Native byte order, announced by the sign of the scale. */
    const char *scale = pn_host_is_little_endian() ? "-1.0" : "1.0";
    if (fprintf(file, "PF\n%d %d\n%s\n", width, height, scale) < 0) {
        return pn_err_set(err, PN_ERROR_IO, "%s: %s", name, strerror(errno ? errno : EIO));
    }
    for (int file_row = 0; file_row < height; file_row++) {
        const float *row = rgb + (size_t)(height - 1 - file_row) * row_values;
        if (fwrite(row, sizeof(float), row_values, file) != row_values) {
            return pn_err_set(err, PN_ERROR_IO, "%s: %s", name, strerror(errno ? errno : EIO));
        }
    }
    return PN_OK;
}
