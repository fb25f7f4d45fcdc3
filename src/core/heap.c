/* heap.c — the binary heap of core/heap.h (the sift and tie rules are stated there). */
#include "core/heap.h"

#include <stdlib.h>

/* Whether x leaves before y: strictly, so equal entries are never before each other. The sifts
 * below are inlined with constant min and ties, one copy an order (the comparison is the hot part
 * of pn_cluster_cut_capped). */
static inline bool before(bool min, bool ties, const pn_heap_entry *x, const pn_heap_entry *y) {
    if (x->key != y->key) return min ? x->key < y->key : x->key > y->key;
    return ties && x->payload < y->payload;
}

/* Puts x at hole i, moving it up past the parents it is before. */
static inline void sift_up(pn_heap_entry *e, size_t i, pn_heap_entry x, bool min, bool ties) {
    while (i > 0) {
        size_t parent = (i - 1) / 2;
        if (!before(min, ties, &x, &e[parent])) break;
        e[i] = e[parent];
        i = parent;
    }
    e[i] = x;
}

/* Puts x at the root hole of e[0, n), moving it down past the first child while that is before
 * it (the right child only when it is before the left). */
static inline void sift_down(pn_heap_entry *e, size_t n, pn_heap_entry x, bool min, bool ties) {
    size_t i = 0;
    for (;;) {
        size_t c = 2 * i + 1;
        if (c >= n) break;
        if (c + 1 < n && before(min, ties, &e[c + 1], &e[c])) c++;
        if (!before(min, ties, &e[c], &x)) break;
        e[i] = e[c];
        i = c;
    }
    e[i] = x;
}

void pn_heap_init(pn_heap *h, int flags) {
    *h = (pn_heap){NULL, 0, 0, flags, false};
}

void pn_heap_init_fixed(pn_heap *h, int flags, pn_heap_entry *storage, size_t capacity) {
    *h = (pn_heap){storage, 0, capacity, flags, true};
}

void pn_heap_free(pn_heap *h) {
    if (!h->fixed) free(h->entries);
    pn_heap_init(h, h->flags);
}

bool pn_heap_reserve(pn_heap *h, size_t n) {
    if (n <= h->capacity) return true;
    if (h->fixed) return false;
    pn_heap_entry *e = realloc(h->entries, n * sizeof *e);
    if (!e) return false;
    h->entries = e;
    h->capacity = n;
    return true;
}

bool pn_heap_push(pn_heap *h, double key, int64_t payload) {
    if (h->count == h->capacity && !pn_heap_reserve(h, h->capacity ? 2 * h->capacity : 64)) return false;
    const pn_heap_entry x = {key, payload};
    const size_t i = h->count++;
    switch (h->flags & (PN_HEAP_MIN | PN_HEAP_TIES_BY_PAYLOAD)) {
    case PN_HEAP_MAX: sift_up(h->entries, i, x, false, false); break;
    case PN_HEAP_MIN: sift_up(h->entries, i, x, true, false); break;
    case PN_HEAP_TIES_BY_PAYLOAD: sift_up(h->entries, i, x, false, true); break;
    default: sift_up(h->entries, i, x, true, true); break;
    }
    return true;
}

pn_heap_entry pn_heap_pop(pn_heap *h) {
    const pn_heap_entry top = h->entries[0], last = h->entries[--h->count];
    const size_t n = h->count;
    if (n == 0) return top;
    switch (h->flags & (PN_HEAP_MIN | PN_HEAP_TIES_BY_PAYLOAD)) {
    case PN_HEAP_MAX: sift_down(h->entries, n, last, false, false); break;
    case PN_HEAP_MIN: sift_down(h->entries, n, last, true, false); break;
    case PN_HEAP_TIES_BY_PAYLOAD: sift_down(h->entries, n, last, false, true); break;
    default: sift_down(h->entries, n, last, true, true); break;
    }
    return top;
}
