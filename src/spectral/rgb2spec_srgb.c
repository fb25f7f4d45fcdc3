/* rgb2spec_srgb.c — the linear sRGB table, generated at build time by tools/rgb2spec_gen.c and
 * linked in as read-only data (the assembler's .incbin of the generated file; the build passes
 * its path as PN_RGB2SPEC_SRGB_BIN). x86-64 and AArch64 Linux are little-endian, the byte order
 * the generator writes. */
#include "spectral/rgb2spec.h"

#include <pthread.h>
#include <stdint.h>
#include <string.h>

#ifndef PN_RGB2SPEC_SRGB_BIN
#error "PN_RGB2SPEC_SRGB_BIN (the generated table's path) must be defined by the build"
#endif

__asm__(".section .rodata\n"
        ".balign 16\n"
        ".type pn_rgb2spec_srgb_blob, @object\n"
        "pn_rgb2spec_srgb_blob:\n"
        ".incbin \"" PN_RGB2SPEC_SRGB_BIN "\"\n"
        "pn_rgb2spec_srgb_blob_end:\n"
        ".previous\n");
extern const unsigned char pn_rgb2spec_srgb_blob[] __asm__("pn_rgb2spec_srgb_blob");
extern const unsigned char pn_rgb2spec_srgb_blob_end[] __asm__("pn_rgb2spec_srgb_blob_end");

static pn_rgb2spec_table g_srgb;
static pthread_once_t g_srgb_once = PTHREAD_ONCE_INIT;

static void srgb_init(void) {
    const unsigned char *p = pn_rgb2spec_srgb_blob;
    size_t size = (size_t)(pn_rgb2spec_srgb_blob_end - pn_rgb2spec_srgb_blob);
    int32_t res = 0;
    if (size < 12 || memcmp(p, "PNR2S001", 8) != 0) return;
    memcpy(&res, p + 8, sizeof res);
    if (res < 3 || size != 12 + sizeof(float) * ((size_t)res + 9 * (size_t)res * res * res)) return;
    /* The blob is 16-byte aligned and the header 12 bytes, so the floats are 4-byte aligned. */
    g_srgb.res = res;
    g_srgb.z_nodes = (float *)(uintptr_t)(p + 12);
    g_srgb.coeffs = (float *)(uintptr_t)(p + 12 + sizeof(float) * (size_t)res);
}

const pn_rgb2spec_table *pn_rgb2spec_srgb(void) {
    pthread_once(&g_srgb_once, srgb_init);
    return g_srgb.res ? &g_srgb : NULL;
}
