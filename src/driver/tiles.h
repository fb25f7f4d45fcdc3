/* tiles.h — the tiled driver's distribution (docs/distributed.md): the image window cut into
 * square tiles aligned to the whole image (tiles.c), the checkpoint log of finished tiles
 * (checkpoint.c) and the hand-out of tiles to MPI ranks (mpi.c). A tile is made of whole blocks,
 * so for integrators with crop-exact pixels (PN_CAP_CROP) the image does not depend on the tiling;
 * an integrator without it (illumcut) renders each tile as one window, in one process as in many. */
#ifndef PN_DRIVER_TILES_H
#define PN_DRIVER_TILES_H

#include "core/error.h"
#include "film/aovs.h"
#include "render/render_job.h"
#include "render/stats.h"

#include <stdatomic.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

typedef struct pn_tile_grid {
    int x0, y0, x1, y1; /* the window [x0, x1) x [y0, y1) */
    int size;           /* tile side in pixels; 0: one tile, the window */
    bool bands;         /* tiles are bands of whole rows of the window (tiles_x 1) */
    int tx0, ty0;       /* the first tile's position in tile units of the whole image */
    int tiles_x, tiles_y, count;
} pn_tile_grid;

/* The tiles of tile side `size` (0: one tile) over the camera's window; with `bands`, bands of
 * `size` rows across the whole window (for integrators whose rows are each one whole, contour). */
void pn_tile_grid_init(pn_tile_grid *g, int x0, int y0, int x1, int y1, int size, bool bands);
/* Tile `tile`'s pixels, clipped to the window: r = {x0, y0, x1, y1}. */
void pn_tile_rect(const pn_tile_grid *g, int tile, int r[4]);
size_t pn_tile_pixel_count(const pn_tile_grid *g, int tile);
/* Copies a tile between the window's estimates (row-major, window width) and a packed tile. */
void pn_tile_copy_out(const pn_tile_grid *g, int tile, const pn_pixel_estimate *window, pn_pixel_estimate *packed);
void pn_tile_copy_in(const pn_tile_grid *g, int tile, const pn_pixel_estimate *packed, pn_pixel_estimate *window);

/* What identifies a render's image (checkpoint.c): a 64-bit FNV-1a hash of the scene's contents
 * (the scene file's bytes, geometry, materials as mapped, lights, textures), the integrator and
 * driver, every option's value in force (checkpoint and tile-times aside), the resolution, window, spp,
 * threshold, seed, specular depth, AOVs and the tiling. */
uint64_t pn_render_key(const pn_render_job *job, const pn_render_settings *settings, int integrator, int driver);

/* The checkpoint: an append-only log, a header then one checksummed record per finished tile. */
typedef struct pn_checkpoint pn_checkpoint;
/* Opens (creating with O_EXCL when absent) the checkpoint at path for a render of `key` over
 * the grid. Tiles it already holds are copied into `window` and marked in done[] (*resumed
 * counts them). A file of another render, another layout or with a corrupt record is refused
 * (PN_ERROR_BAD_INPUT naming the file and why); a torn last record (a write cut short by a
 * kill) is dropped and the file truncated there. */
pn_status pn_checkpoint_open(const char *path, uint64_t key, const pn_tile_grid *g, pn_pixel_estimate *window,
                             unsigned char *done, int *resumed, pn_checkpoint **out, pn_err *err);
/* Appends tile `tile` (its packed estimates) and syncs it to disk. */
pn_status pn_checkpoint_append(pn_checkpoint *c, int tile, const pn_pixel_estimate *packed, size_t count, pn_err *err);
void pn_checkpoint_close(pn_checkpoint *c);

/* The work of a distributed render (render.c provides it, mpi.c runs it). */
typedef struct pn_tile_work {
    const pn_tile_grid *grid;
    /* Renders the tile into the window's estimates and, when packed is not NULL, packs it. */
    pn_status (*render)(void *user, int tile, pn_pixel_estimate *packed);
    /* Rank 0: a finished tile (packed) into the window and the checkpoint. */
    pn_status (*store)(void *user, int tile, const pn_pixel_estimate *packed, bool local);
    void *user;
    unsigned char *done; /* tiles already finished (checkpoint) */
    const atomic_int *cancel;
    size_t max_tile_pixels;
    struct pn_progress *progress; /* rank 0: tiles stored over tiles */
} pn_tile_work;

/* What every rank did, gathered on rank 0. */
#define PN_DIST_MAX_RANKS 256
typedef struct pn_dist_report {
    int ranks;
    double busy_seconds[PN_DIST_MAX_RANKS]; /* time each rank spent rendering tiles */
    uint32_t tiles[PN_DIST_MAX_RANKS];      /* tiles each rank rendered */
} pn_dist_report;

/* mpi.c. Whether pn_mpi_init attached this process to an MPI job of more than one rank, and
 * this rank. */
int pn_dist_size(void);
int pn_dist_rank(void);
/* Collective: every rank's status after its preparation and its render key; on rank 0 a
 * failure or a key that differs names the rank. Returns the combined status on every rank. */
pn_status pn_dist_start(pn_context ctx, pn_status local, uint64_t key);
/* Collective: runs the tiles over the ranks, rank 0 handing them out one at a time as ranks ask
 * (and rendering too, on a thread of its own). Returns on every rank; rank 0 holds every tile. */
pn_status pn_dist_run_tiles(pn_context ctx, pn_tile_work *work, pn_dist_report *report);
/* Collective: sums the additive statistics the integrators report over the ranks into rank 0's. */
void pn_dist_reduce_stats(pn_render_stats *stats);

#endif
