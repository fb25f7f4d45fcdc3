/* tiles.c — the tiles of the tiled driver's distribution (tiles.h): a grid of square tiles
 * aligned to the whole image (so that a crop or a --piece cuts the same tiles as the whole
 * window), and the copies between a window of estimates and one packed tile. */
#include "driver/tiles.h"

#include <string.h>

void pn_tile_grid_init(pn_tile_grid *g, int x0, int y0, int x1, int y1, int size, bool bands) {
    memset(g, 0, sizeof *g);
    g->x0 = x0;
    g->y0 = y0;
    g->x1 = x1;
    g->y1 = y1;
    g->size = size;
    if (size <= 0) {
        g->tiles_x = g->tiles_y = g->count = 1;
        return;
    }
    g->bands = bands;
    g->tx0 = bands ? 0 : x0 / size;
    g->ty0 = y0 / size;
    g->tiles_x = bands ? 1 : (x1 - 1) / size - g->tx0 + 1;
    g->tiles_y = (y1 - 1) / size - g->ty0 + 1;
    g->count = g->tiles_x * g->tiles_y;
}

void pn_tile_rect(const pn_tile_grid *g, int tile, int r[4]) {
    if (g->size <= 0) {
        r[0] = g->x0, r[1] = g->y0, r[2] = g->x1, r[3] = g->y1;
        return;
    }
    int tx = g->tx0 + tile % g->tiles_x, ty = g->ty0 + tile / g->tiles_x;
    r[0] = tx * g->size > g->x0 ? tx * g->size : g->x0;
    r[1] = ty * g->size > g->y0 ? ty * g->size : g->y0;
    r[2] = (tx + 1) * g->size < g->x1 ? (tx + 1) * g->size : g->x1;
    r[3] = (ty + 1) * g->size < g->y1 ? (ty + 1) * g->size : g->y1;
    if (g->bands) r[0] = g->x0, r[2] = g->x1;
}

size_t pn_tile_pixel_count(const pn_tile_grid *g, int tile) {
    int r[4];
    pn_tile_rect(g, tile, r);
    return (size_t)(r[2] - r[0]) * (size_t)(r[3] - r[1]);
}

static void tile_copy(const pn_tile_grid *g, int tile, pn_pixel_estimate *window, pn_pixel_estimate *packed, bool out) {
    int r[4];
    pn_tile_rect(g, tile, r);
    size_t w = (size_t)(r[2] - r[0]), width = (size_t)(g->x1 - g->x0);
    for (int y = r[1]; y < r[3]; y++) {
        pn_pixel_estimate *row = window + (size_t)(y - g->y0) * width + (size_t)(r[0] - g->x0);
        pn_pixel_estimate *p = packed + (size_t)(y - r[1]) * w;
        if (out)
            memcpy(p, row, w * sizeof *p);
        else
            memcpy(row, p, w * sizeof *p);
    }
}

void pn_tile_copy_out(const pn_tile_grid *g, int tile, const pn_pixel_estimate *window, pn_pixel_estimate *packed) {
    tile_copy(g, tile, (pn_pixel_estimate *)window, packed, true);
}

void pn_tile_copy_in(const pn_tile_grid *g, int tile, const pn_pixel_estimate *packed, pn_pixel_estimate *window) {
    tile_copy(g, tile, window, (pn_pixel_estimate *)packed, false);
}
