/* rgb2spec_gen.c — build-time generator of the linear sRGB table of spectral/rgb2spec.h.
 *
 * usage: rgb2spec_gen RES THREADS OUT.bin
 * The file is the table as the library reads it (spectral/rgb2spec_srgb.c): the 8-byte magic
 * "PNR2S001", the resolution as a little-endian int32, then res float z nodes and
 * 9 res³ float coefficients, all little-endian IEEE 754. It is written to OUT.bin.tmp and renamed,
 * so an interrupted build leaves no truncated table.
 */
#include "spectral/rgb2spec.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int main(int argc, char **argv) {
    if (argc != 4) {
        fprintf(stderr, "usage: rgb2spec_gen RES THREADS OUT.bin\n");
        return 2;
    }
    int res = atoi(argv[1]), threads = atoi(argv[2]);
    pn_rgb2spec_table table;
    if (!pn_rgb2spec_table_build(&table, res, threads)) {
        fprintf(stderr, "rgb2spec_gen: cannot build a table of resolution %d\n", res);
        return 1;
    }
    char tmp[4096];
    snprintf(tmp, sizeof tmp, "%s.tmp", argv[3]);
    FILE *f = fopen(tmp, "wb");
    int32_t r = res;
    size_t n = 9 * (size_t)res * res * res;
    bool ok = f && fwrite("PNR2S001", 1, 8, f) == 8 && fwrite(&r, sizeof r, 1, f) == 1 &&
              fwrite(table.z_nodes, sizeof(float), (size_t)res, f) == (size_t)res &&
              fwrite(table.coeffs, sizeof(float), n, f) == n;
    if (f && fclose(f) != 0) ok = false;
    pn_rgb2spec_table_free(&table);
    if (!ok || rename(tmp, argv[3]) != 0) {
        perror(argv[3]);
        remove(tmp);
        return 1;
    }
    return 0;
}
