/* Shared by the compiled kernels (_kernels.c, _kernels_timing.c): sizes, searches, NaN-aware
 * minimum and maximum. */
#ifndef GP_KERNELS_H
#define GP_KERNELS_H

#include <math.h>
#include <stdint.h>

typedef int64_t idx_t;

/* Number of entries of a (size n) that are <= x (numpy searchsorted(a, x, side='right')). */
static inline idx_t upper(const double *a, idx_t n, double x)
{
    idx_t lo = 0, hi = n;
    while (lo < hi) {
        idx_t mid = lo + (hi - lo) / 2;
        if (a[mid] <= x) lo = mid + 1; else hi = mid;
    }
    return lo;
}

/* upper(a, n, x), first trying the answer of the previous call (*hint) and the next one: sorted
 * times (the usual case) then cost O(1) per sample; *hint is updated. */
static inline idx_t upper_hint(const double *a, idx_t n, double x, idx_t *hint)
{
    idx_t h = *hint;
    if (h > n) h = n;
    if ((h == 0 || a[h - 1] <= x) && (h == n || x < a[h])) return h;
    if (h < n && a[h] <= x && (h + 1 == n || x < a[h + 1])) { *hint = h + 1; return h + 1; }
    h = upper(a, n, x);
    *hint = h;
    return h;
}

/* Number of entries of a that are < x (numpy searchsorted(a, x, side='left')). */
static inline idx_t lower(const double *a, idx_t n, double x)
{
    idx_t lo = 0, hi = n;
    while (lo < hi) {
        idx_t mid = lo + (hi - lo) / 2;
        if (a[mid] < x) lo = mid + 1; else hi = mid;
    }
    return lo;
}

/* np.maximum / np.minimum: NaN in either argument gives NaN (fmax and fmin would drop it). */
static inline double nmax(double a, double b) { return (isnan(a) || a >= b) ? a : b; }
static inline double nmin(double a, double b) { return (isnan(a) || a <= b) ? a : b; }
static inline double clampd(double x, double lo, double hi) { return nmin(nmax(x, lo), hi); }
static inline idx_t clampi(idx_t x, idx_t lo, idx_t hi) { return x < lo ? lo : (x > hi ? hi : x); }

#endif
