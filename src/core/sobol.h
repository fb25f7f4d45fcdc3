/* sobol.h — Owen-scrambled Sobol' points for quasi-Monte Carlo sampling.
 *
 * Dimension 0 is the van der Corput sequence (bit reversal of the index); dimensions
 * 1..PN_SOBOL_DIMS-1 use the generator matrices of Joe and Kuo's new-joe-kuo-6.21201 direction
 * numbers (dimensions 2..128 of their list). Every dimension is randomised with a hash-based
 * nested uniform (Owen) scramble whose seed is derived from the caller's `scramble` value and
 * the dimension, so:
 *   - each 1-D projection of the first 2^k points is stratified in 2^k equal intervals,
 *   - dimensions (0, 1) of the first 2^k points form a (0, k, 2)-net,
 *   - different `scramble` values give statistically independent randomisations, and
 *     scramble == 0 is just one more (deterministic) randomisation.
 * Dimensions >= PN_SOBOL_DIMS have no direction numbers: they return a hash of
 * (index, dim, scramble), i.e. plain pseudo-random values without stratification.
 */
#ifndef PN_CORE_SOBOL_H
#define PN_CORE_SOBOL_H

#include <stdbool.h>
#include <stdint.h>

/* Number of dimensions backed by real Sobol' generator matrices. */
#define PN_SOBOL_DIMS 128

/* The index-th scrambled point in dimension dim as a 32-bit fixed-point fraction. */
uint32_t pn_sobol_sample_u32(uint32_t index, int dim, uint32_t scramble);

/* The same point as a float in [0, 1); the largest possible value is 0x1.fffffep-1f. */
float pn_sobol_sample(uint32_t index, int dim, uint32_t scramble);

/* The scramble seed pn_sobol_sample_u32 derives from (dim, scramble) for dim in
 * [0, PN_SOBOL_DIMS): a caller drawing many points of the same dimensions hashes it once. */
uint32_t pn_sobol_seed(int dim, uint32_t scramble);

/* Points index of the dimensions first_dim .. first_dim + count - 1 (all within
 * [0, PN_SOBOL_DIMS)), each as pn_sobol_sample would give it, from their seeds
 * (seeds[i] = pn_sobol_seed(first_dim + i, scramble)): the same numbers, bit for bit. */
void pn_sobol_samples(uint32_t index, int first_dim, int count, const uint32_t *seeds, float *out);

/* The unscrambled Sobol' point (32-bit fraction); dims outside [0, PN_SOBOL_DIMS) give 0.
 * Exposed for tests and for callers that apply their own randomisation. */
uint32_t pn_sobol_raw_u32(uint32_t index, int dim);

/* The same point computed bit by bit from the generator matrix (pn_sobol_raw_u32 uses byte
 * tables for the first dimensions); for tests. */
uint32_t pn_sobol_raw_u32_by_bits(uint32_t index, int dim);

/* Self-check for tests: rebuilds every generator matrix from the primitive polynomials and
 * initial direction numbers and compares it with the precomputed tables. */
bool pn_sobol_tables_consistent(void);

#endif
