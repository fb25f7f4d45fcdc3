/* rng.h — integer hashing and a small pseudo-random generator (header-only).
 *
 * pn_hash64 is the splitmix64 output function applied to a Weyl-offset input, so hashing 0
 * does not give 0. pn_hash3 folds three values into one well-mixed 64-bit key (for seeding
 * per-pixel / per-pass streams). pn_rng is O'Neill's PCG32 (XSH-RR output on a 64-bit LCG):
 * tiny state, 2^63 selectable streams, good statistical quality for Monte Carlo use.
 *
 * Everything here is a pure function of its arguments or of the generator passed in; there is
 * no shared state, so generators may be used freely one per thread.
 */
#ifndef PN_CORE_RNG_H
#define PN_CORE_RNG_H

#include <stdint.h>

/* Bijective 64-bit mixer (splitmix64 finaliser on x + golden-ratio increment). */
static inline uint64_t pn_hash64(uint64_t x) {
    x += UINT64_C(0x9e3779b97f4a7c15);
    x = (x ^ (x >> 30)) * UINT64_C(0xbf58476d1ce4e5b9);
    x = (x ^ (x >> 27)) * UINT64_C(0x94d049bb133111eb);
    return x ^ (x >> 31);
}

/* Order-sensitive hash of three values: pn_hash3(a, b, c) != pn_hash3(b, a, c) in general. */
static inline uint64_t pn_hash3(uint64_t a, uint64_t b, uint64_t c) {
    uint64_t h = pn_hash64(a);
    h = pn_hash64(h ^ (b * UINT64_C(0xd6e8feb86659fd93)));
    h = pn_hash64(h ^ (c * UINT64_C(0xa0761d6478bd642f)));
    return h;
}

/* A uniform float in [0, 1) from a hash value (its top 24 bits). */
static inline float pn_hash_unit(uint64_t h) {
    return (float)(h >> 40) * 0x1p-24f;
}

/* PCG32 state. Seed with pn_rng_seed before use. */
typedef struct pn_rng {
    uint64_t state;
    uint64_t inc; /* always odd; selects the stream */
} pn_rng;

#define PN_PCG32_MULT UINT64_C(6364136223846793005)

/* Uniform 32-bit value. */
static inline uint32_t pn_rng_u32(pn_rng *rng) {
    uint64_t old = rng->state;
    rng->state = old * PN_PCG32_MULT + rng->inc;
    uint32_t xorshifted = (uint32_t)(((old >> 18) ^ old) >> 27);
    uint32_t rot = (uint32_t)(old >> 59);
    return (xorshifted >> rot) | (xorshifted << ((32u - rot) & 31u));
}

/* Initialises the generator; different `stream` values give independent sequences even for
 * the same seed. */
static inline void pn_rng_seed(pn_rng *rng, uint64_t seed, uint64_t stream) {
    rng->state = 0;
    rng->inc = (stream << 1) | 1u;
    (void)pn_rng_u32(rng);
    rng->state += seed;
    (void)pn_rng_u32(rng);
}

/* Uniform float in [0, 1): the top 24 bits scaled by 2^-24, so the result is exact and the
 * largest value is 1 - 2^-24 (never 1.0f). */
static inline float pn_rng_float(pn_rng *rng) {
    return (float)(pn_rng_u32(rng) >> 8) * 0x1p-24f;
}

/* Uniform integer in [0, n) for n > 0 (Lemire's multiply-shift; the bias is below 2^-32 * n
 * and irrelevant for sampling purposes). Returns 0 for n == 0. */
static inline uint32_t pn_rng_below(pn_rng *rng, uint32_t n) {
    return (uint32_t)(((uint64_t)pn_rng_u32(rng) * (uint64_t)n) >> 32);
}

#endif
