/* test_heap.c — core/heap: both orders and both tie rules against references on random keys
 * drawn from a few values (so that most comparisons are ties), pushes and pops interleaved,
 * growth from an empty heap, and a fixed heap's capacity.
 *
 * The tie rule without PN_HEAP_TIES_BY_PAYLOAD is checked against an independent swap-based
 * sift (the form painter.c and env_regions.c had) array for array, since renders depend on it:
 * lightcuts sums the open bounds in array order and env regions split in its tie order.
 */
#include "harness.h"

#include "core/heap.h"
#include "core/rng.h"

#include <stdint.h>

static const double tie_keys[] = {-1.0, 0.0, 0.5, 2.0, INFINITY};

static double random_key(pn_rng *g) {
    return tie_keys[pn_rng_below(g, (uint32_t)(sizeof tie_keys / sizeof *tie_keys))];
}

/* Whether x leaves before y by (key, payload) in the heap's order. */
static bool ref_before(int flags, pn_heap_entry x, pn_heap_entry y) {
    if (x.key != y.key) return (flags & PN_HEAP_MIN) ? x.key < y.key : x.key > y.key;
    return x.payload < y.payload;
}

/* The reference of the payload rule: a sorted array (inserted in place), its first entry next. */
typedef struct sorted_ref {
    pn_heap_entry e[4096];
    int n;
} sorted_ref;

static void ref_insert(sorted_ref *r, int flags, pn_heap_entry x) {
    int i = r->n++;
    while (i > 0 && ref_before(flags, x, r->e[i - 1])) {
        r->e[i] = r->e[i - 1];
        i--;
    }
    r->e[i] = x;
}

static pn_heap_entry ref_take(sorted_ref *r) {
    pn_heap_entry x = r->e[0];
    memmove(r->e, r->e + 1, (size_t)(--r->n) * sizeof *r->e);
    return x;
}

static bool same(pn_heap_entry a, pn_heap_entry b) {
    return a.key == b.key && a.payload == b.payload;
}

/* Every parent is not after its children (the heap property). */
static bool heap_valid(const pn_heap *h) {
    for (size_t i = 1; i < h->count; i++) {
        pn_heap_entry parent = h->entries[(i - 1) / 2], child = h->entries[i];
        bool child_first = (h->flags & PN_HEAP_TIES_BY_PAYLOAD) ? ref_before(h->flags, child, parent)
                           : (h->flags & PN_HEAP_MIN)           ? child.key < parent.key
                                                                : child.key > parent.key;
        if (child_first) return false;
    }
    return true;
}

/* Pushes of random keys with many ties, then pops: the sorted (key, payload) sequence, for both
 * orders; payloads repeat too (equal entries are interchangeable). */
static void test_ties_by_payload_sorted(void) {
    static sorted_ref ref;
    for (int order = 0; order < 2; order++) {
        const int flags = (order ? PN_HEAP_MIN : PN_HEAP_MAX) | PN_HEAP_TIES_BY_PAYLOAD;
        pn_rng g;
        pn_rng_seed(&g, 11, (uint64_t)order);
        pn_heap h;
        pn_heap_init(&h, flags);
        ref.n = 0;
        for (int i = 0; i < 3000; i++) {
            pn_heap_entry x = {random_key(&g), (int64_t)pn_rng_below(&g, 1000) - 500};
            CHECK(pn_heap_push(&h, x.key, x.payload));
            ref_insert(&ref, flags, x);
        }
        CHECK(heap_valid(&h));
        int wrong = 0;
        while (h.count > 0) wrong += !same(pn_heap_pop(&h), ref_take(&ref));
        CHECK_MSG(wrong == 0, "%d pops out of order", wrong);
        CHECK(ref.n == 0);
        pn_heap_free(&h);
    }
}

/* Pushes and pops interleaved at random (the heap grows and shrinks), each pop against the
 * reference's first entry, and the top agreeing with the next pop. */
static void test_interleaved(void) {
    static sorted_ref ref;
    for (int order = 0; order < 2; order++) {
        const int flags = (order ? PN_HEAP_MIN : PN_HEAP_MAX) | PN_HEAP_TIES_BY_PAYLOAD;
        pn_rng g;
        pn_rng_seed(&g, 12, (uint64_t)order);
        pn_heap h;
        pn_heap_init(&h, flags);
        ref.n = 0;
        int wrong = 0, pops = 0;
        for (int step = 0; step < 20000; step++) {
            bool push = ref.n == 0 || (ref.n < 4000 && pn_rng_below(&g, 100) < (step < 10000 ? 60u : 40u));
            if (push) {
                pn_heap_entry x = {random_key(&g), (int64_t)pn_rng_below(&g, 50)};
                CHECK(pn_heap_push(&h, x.key, x.payload));
                ref_insert(&ref, flags, x);
            } else {
                pn_heap_entry top = pn_heap_top(&h), x = pn_heap_pop(&h), r = ref_take(&ref);
                wrong += !same(x, r) || !same(top, x);
                pops++;
            }
            if (h.count != (size_t)ref.n) wrong++;
        }
        CHECK(pops > 5000);
        CHECK_MSG(wrong == 0, "%d mismatches", wrong);
        CHECK(heap_valid(&h));
        pn_heap_free(&h);
    }
}

/* From an empty heap (no storage) through several reallocations; after pn_heap_clear and
 * pn_heap_free it is empty and usable again. */
static void test_growth_from_empty(void) {
    pn_heap h;
    pn_heap_init(&h, PN_HEAP_MIN | PN_HEAP_TIES_BY_PAYLOAD);
    CHECK(h.count == 0 && h.capacity == 0 && h.entries == NULL);
    const int n = 5000;
    for (int i = 0; i < n; i++) CHECK(pn_heap_push(&h, (double)((i * 7919) % n), i));
    CHECK(h.count == (size_t)n && h.capacity >= (size_t)n);
    int wrong = 0;
    for (int i = 0; i < n; i++) {
        pn_heap_entry e = pn_heap_pop(&h);
        wrong += e.key != (double)i || (e.payload * 7919) % n != i;
    }
    CHECK_MSG(wrong == 0, "%d pops out of order", wrong);
    CHECK(pn_heap_push(&h, 3.0, 1) && pn_heap_push(&h, 1.0, 2));
    pn_heap_clear(&h);
    CHECK(h.count == 0);
    pn_heap_free(&h);
    CHECK(h.entries == NULL && h.capacity == 0);
    CHECK(pn_heap_push(&h, 2.0, 9) && pn_heap_pop(&h).payload == 9);
    pn_heap_free(&h);
}

/* A heap in the caller's storage: full at its capacity (a failed push changes nothing), never
 * reallocated. */
static void test_fixed_storage(void) {
    pn_heap_entry storage[8];
    pn_heap h;
    pn_heap_init_fixed(&h, PN_HEAP_MAX | PN_HEAP_TIES_BY_PAYLOAD, storage, 8);
    for (int i = 0; i < 8; i++) CHECK(pn_heap_push(&h, (double)(i % 3), i));
    CHECK(!pn_heap_push(&h, 10.0, 99));
    CHECK(!pn_heap_reserve(&h, 9));
    CHECK(h.count == 8 && h.entries == storage);
    const int64_t expect[8] = {2, 5, 1, 4, 7, 0, 3, 6}; /* key 2 (2, 5), key 1 (1, 4, 7), key 0 */
    for (int i = 0; i < 8; i++) CHECK(pn_heap_pop(&h).payload == expect[i]);
    pn_heap_free(&h); /* the storage is the caller's */
}

/* The sift without the payload rule, written independently with swaps: the entry at i moves
 * while the one it meets is strictly after it (keys only). */
typedef struct swap_ref {
    pn_heap_entry e[4096];
    size_t n;
    int flags;
} swap_ref;

static bool key_before(const swap_ref *r, size_t a, size_t b) {
    return (r->flags & PN_HEAP_MIN) ? r->e[a].key < r->e[b].key : r->e[a].key > r->e[b].key;
}

static void swap_at(swap_ref *r, size_t a, size_t b) {
    pn_heap_entry t = r->e[a];
    r->e[a] = r->e[b];
    r->e[b] = t;
}

static void swap_push(swap_ref *r, pn_heap_entry x) {
    size_t i = r->n++;
    r->e[i] = x;
    while (i > 0 && key_before(r, i, (i - 1) / 2)) {
        swap_at(r, i, (i - 1) / 2);
        i = (i - 1) / 2;
    }
}

static pn_heap_entry swap_pop(swap_ref *r) {
    pn_heap_entry top = r->e[0];
    r->e[0] = r->e[--r->n];
    size_t i = 0;
    for (;;) {
        size_t l = 2 * i + 1, m = i;
        if (l < r->n && key_before(r, l, m)) m = l;
        if (l + 1 < r->n && key_before(r, l + 1, m)) m = l + 1;
        if (m == i) break;
        swap_at(r, i, m);
        i = m;
    }
    return top;
}

/* Without PN_HEAP_TIES_BY_PAYLOAD: the array equals the swap-based sift's after every call, on
 * keys with many ties, both orders; and a small case by hand: five equal keys leave as the
 * first pushed, then the others last pushed first. */
static void test_sift_tie_order(void) {
    static swap_ref ref;
    for (int order = 0; order < 2; order++) {
        const int flags = order ? PN_HEAP_MIN : PN_HEAP_MAX;
        pn_rng g;
        pn_rng_seed(&g, 13, (uint64_t)order);
        pn_heap h;
        pn_heap_init(&h, flags);
        ref.n = 0;
        ref.flags = flags;
        int wrong = 0;
        for (int step = 0; step < 20000; step++) {
            if (ref.n == 0 || (ref.n < 4000 && pn_rng_below(&g, 100) < 55u)) {
                pn_heap_entry x = {random_key(&g), step};
                CHECK(pn_heap_push(&h, x.key, x.payload));
                swap_push(&ref, x);
            } else {
                wrong += !same(pn_heap_pop(&h), swap_pop(&ref));
            }
            if (h.count != ref.n || (step % 97 == 0 && memcmp(h.entries, ref.e, ref.n * sizeof *ref.e) != 0)) wrong++;
        }
        CHECK_MSG(wrong == 0, "%d mismatches", wrong);
        CHECK(heap_valid(&h));
        pn_heap_free(&h);
    }
    pn_heap h;
    pn_heap_init(&h, PN_HEAP_MAX);
    for (int i = 0; i < 5; i++) CHECK(pn_heap_push(&h, 1.0, i));
    const int64_t expect[5] = {0, 4, 3, 2, 1};
    for (int i = 0; i < 5; i++) CHECK(pn_heap_pop(&h).payload == expect[i]);
    pn_heap_free(&h);
}

PN_TESTS(TEST(test_ties_by_payload_sorted), TEST(test_interleaved), TEST(test_growth_from_empty),
         TEST(test_fixed_storage), TEST(test_sift_tie_order))
