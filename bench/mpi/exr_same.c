/* exr_same.c — whether two EXR files hold the same pixels in every layer, whatever their data and
 * display windows (a crop written before and after crop EXRs carried their data window: the
 * bytes of the header differ, the pixels must not). Exit 0: same; 1: different; 2: unreadable.
 *   build: cc -O2 -Iinclude bench/mpi/exr_same.c -Lbuild -lpenumbra -o build/exr_same
 *   usage: exr_same A.exr B.exr */
#include <penumbra/penumbra.h>

#include <stdio.h>
#include <string.h>

int main(int argc, char **argv) {
    if (argc != 3) return 2;
    pn_context ctx = pn_context_new();
    pn_image a = NULL, b = NULL;
    if (pn_image_read_layers(ctx, argv[1], &a) != PN_OK || pn_image_read_layers(ctx, argv[2], &b) != PN_OK) {
        fprintf(stderr, "%s\n", pn_context_error_message(ctx));
        return 2;
    }
    int same = pn_image_width(a) == pn_image_width(b) && pn_image_height(a) == pn_image_height(b) &&
               pn_image_layer_count(a) == pn_image_layer_count(b);
    size_t px = (size_t)pn_image_width(a) * (size_t)pn_image_height(a);
    for (int l = 0; same && l < pn_image_layer_count(a); l++)
        same = strcmp(pn_image_layer_name(a, l), pn_image_layer_name(b, l)) == 0 &&
               pn_image_layer_channels(a, l) == pn_image_layer_channels(b, l) &&
               memcmp(pn_image_layer_data(a, l), pn_image_layer_data(b, l),
                      px * (size_t)pn_image_layer_channels(a, l) * sizeof(float)) == 0;
    pn_image_free(a);
    pn_image_free(b);
    pn_context_free(ctx);
    return same ? 0 : 1;
}
