/* The time laws' compiled kernels (see _kernels.c for the list and the conventions). */
#include <string.h>

#include "_kernels.h"

void gp_point_ratios(idx_t K, idx_t dof, const double *a, const double *b, const double *c, const double *sd,
                     const double *sdd, const double *sddd, const double *vmax, const double *amax,
                     const double *jmax, double *out);

/* q' and q'' (a, b) at r from a step's cubic Hermite coefficients c (rows 0-7 of
 * sampling.PathSamples.coef, `plane` apart), by the Horner steps of its numpy code. */
static inline void hermite(const double *c, idx_t plane, double r, double *a, double *b)
{
    double x = c[3 * plane];
    x *= r; x += c[2 * plane]; x *= r; x += c[plane]; x *= r; x += c[0];
    double y = c[7 * plane];
    y *= r; y += c[6 * plane]; y *= r; y += c[5 * plane]; y *= r; y += c[4 * plane];
    *a = x;
    *b = y;
}

/* The smoothed law at times t (m,). pieces (6, L): tau, duration, s_start, span, s_end, T*;
 * seg (6, S): start, s0, v0, u, S1, S2 of each s* segment, searched by seg_key (S,).
 * Outputs s, sd, sdd and (when sddd is not NULL) sddd, each (m,). */
void gp_piecewise_evaluate(idx_t m, const double *t, idx_t L, const double *offs, const double *pieces,
                           double key_step, idx_t S, const double *seg_key, const double *seg,
                           double *s_out, double *sd_out, double *sdd_out, double *sddd_out)
{
    const double duration = offs[L];
    const double snap = 1e-12 * fmax(1.0, duration);
    idx_t hints[3] = {0, 0, 0};
    for (idx_t i = 0; i < m; ++i) {
        double ti = t[i], local, key_off = 0.0;
        idx_t p = 0;
        if (L == 1) {
            local = clampd(ti, 0.0, duration);
        } else {
            idx_t j = clampi(lower(offs, L + 1, ti), 1, L);
            double near = fabs(ti - offs[j - 1]) <= fabs(ti - offs[j]) ? offs[j - 1] : offs[j];
            if (fabs(ti - near) <= snap) ti = near;
            p = clampi(upper(offs, L + 1, ti) - 1, 0, L - 1);
            double dur = pieces[L + p];
            local = ti >= offs[p + 1] ? dur : ti - offs[p];
            local = clampd(local, 0.0, dur);
            key_off = (double)p * key_step;
        }
        const double tau = pieces[p], dur = pieces[L + p], s_start = pieces[2 * L + p];
        const double span = pieces[3 * L + p], s_end = pieces[4 * L + p];
        double w2[3], w1[3], w0[3], w3[3];
        double q = local;
        for (int k = 0; k < 3; ++k) {
            if (k == 1) q = local - tau;
            else if (k == 2) q = q - tau;
            double key = L > 1 ? q + key_off : q;
            idx_t g = upper_hint(seg_key, S, key, &hints[k]) - 1;
            if (g < 0) g = 0;
            const double start = seg[g], s0 = seg[S + g], v0 = seg[2 * S + g], u = seg[3 * S + g];
            const double S1 = seg[4 * S + g], S2 = seg[5 * S + g];
            const double r = q - start, ru = r * u;
            double a = ru / 24.0;
            a += v0 / 6.0; a *= r; a += 0.5 * s0; a *= r; a += S1; a *= r; a += S2;
            w2[k] = a;
            double b = ru / 6.0;
            b += 0.5 * v0; b *= r; b += s0; b *= r; b += S1;
            w1[k] = b;
            double c = 0.5 * ru;
            c += v0; c *= r; c += s0;
            w0[k] = c;
            w3[k] = ru + v0;
        }
        const double inv = 1.0 / (tau * tau);
#define SECOND_DIFFERENCE(y) (((y[0] - 2.0 * y[1]) + y[2]) * inv)
        double s = s_start + clampd(SECOND_DIFFERENCE(w2), 0.0, span);
        double sd = nmax(SECOND_DIFFERENCE(w1), 0.0);
        double sdd = SECOND_DIFFERENCE(w0);
        double sddd = SECOND_DIFFERENCE(w3);
#undef SECOND_DIFFERENCE
        if (local >= dur) { s = s_end; sd = sdd = sddd = 0.0; }
        else if (local <= 0.0) { s = s_start; sd = sdd = sddd = 0.0; }
        s_out[i] = s;
        sd_out[i] = sd;
        sdd_out[i] = sdd;
        if (sddd_out) sddd_out[i] = sddd;
    }
}

/* s* of one piece at local time r: integral S1, s* - s_start, sdot*, sddot* (box_filter.StarPiece.at).
 * The piece's steps are t0, s0, v0, u, S1 (each n entries); t_star, span, S1_end its end. */
static void star_at(double r, idx_t n, const double *t0, const double *s0, const double *v0, const double *u,
                    const double *S1, double t_star, double span, double S1_end, idx_t *hint, double out[4])
{
    idx_t k = clampi(upper_hint(t0, n, r, hint) - 1, 0, n - 1);
    double d = r - t0[k];
    double a = s0[k], v = v0[k], uk = u[k];
    double I = S1[k] + d * (a + d * (0.5 * v + d * uk / 6.0));
    double s = a + d * (v + 0.5 * uk * d);
    double vel = v + uk * d;
    if (r <= 0.0) { out[0] = 0.0; out[1] = 0.0; out[2] = 0.0; out[3] = 0.0; return; }
    if (r >= t_star) { out[0] = S1_end + span * (r - t_star); out[1] = span; out[2] = 0.0; out[3] = 0.0; return; }
    out[0] = I; out[1] = s; out[2] = vel; out[3] = uk;
}

/* The box-filtered law at times t (m,). Pieces: L of them, piece i's steps at first[i] ..
 * first[i + 1] - 1 of the step tables t0, s0, v0, u, S1; ends (4, L): t_star, span, S1_end, s_start;
 * width (L,), offs (L + 1,). Outputs as gp_piecewise_evaluate. */
void gp_box_evaluate(idx_t m, const double *t, idx_t L, const double *offs, const double *width,
                     const double *ends, const idx_t *first, const double *t0, const double *s0,
                     const double *v0, const double *u, const double *S1,
                     double *s_out, double *sd_out, double *sdd_out, double *sddd_out)
{
    const double duration = offs[L];
    const double snap = 1e-12 * fmax(1.0, duration);
    idx_t hints[2] = {0, 0}, last_piece = -1;
    for (idx_t i = 0; i < m; ++i) {
        double ti = clampd(t[i], 0.0, duration);
        idx_t p = clampi(upper(offs, L + 1, ti) - 1, 0, L - 1);
        const double w = width[p], t_star = ends[p], span = ends[L + p], S1_end = ends[2 * L + p];
        const double s_start = ends[3 * L + p];
        const double dur = t_star + w;
        double r = clampd(ti - offs[p], 0.0, dur);
        if (fabs(r - dur) <= snap) r = dur;
        const idx_t f = first[p], n = first[p + 1] - first[p];
        if (p != last_piece) { hints[0] = hints[1] = 0; last_piece = p; }
        double A[4], B[4];
        star_at(r, n, t0 + f, s0 + f, v0 + f, u + f, S1 + f, t_star, span, S1_end, &hints[0], A);
        star_at(r - w, n, t0 + f, s0 + f, v0 + f, u + f, S1 + f, t_star, span, S1_end, &hints[1], B);
        double s = clampd((A[0] - B[0]) / w, 0.0, span);
        double sd = nmax((A[1] - B[1]) / w, 0.0);
        double sdd = (A[2] - B[2]) / w;
        double sddd = (A[3] - B[3]) / w;
        if (r <= 0.0 || r >= dur) { s = 0.0; sd = sdd = sddd = 0.0; }
        s_out[i] = s_start + (r >= dur ? span : s);
        sd_out[i] = sd;
        sdd_out[i] = sdd;
        if (sddd_out) sddd_out[i] = sddd;
    }
}

/* smoothing.build_piecewise_law: the optimal profile x (n + 1,) on nodes s (n + 1,), split at its
 * rests (indices rests (L + 1,), x <= 0 there) into L rest-to-rest pieces, each smoothed by a kernel
 * of half-width tau. K = rests[L] - rests[0] steps. Outputs: pieces (6, L) (tau, duration, s_start,
 * span, s_end, T*), offsets (L + 1,), seg (6, K + 2 L) and seg_key (K + 2 L,), node_s and node_t
 * (K + L,), key_step (1,). Same formulas and summation order as the numpy code; valley_depth is
 * smoothing.VALLEY_DEPTH. node_t serves as scratch for each piece's running maxima from the right
 * before it is filled. */
void gp_build_piecewise(const double *s, const double *x, idx_t L, const idx_t *rests, double smoothing,
                        double valley_depth, double *pieces, double *offs, double *seg, double *seg_key, double *node_s,
                        double *node_t, double *key_step_out)
{
    const idx_t K = rests[L] - rests[0], S = K + 2 * L;
    for (idx_t i = 0; i < 6 * S; ++i) seg[i] = 0.0;
    double dur_max = 0.0;
    offs[0] = 0.0;
    for (idx_t p = 0; p < L; ++p) {
        const idx_t a = rests[p], b = rests[p + 1];
        const double start_s = s[a];
        /* deep speed valleys inside the piece (smoothing._valleys) */
        double *right = node_t, left = -INFINITY, valleys = 0.0;
        right[b - a] = sqrt(nmax(x[b], 0.0));
        for (idx_t i = b - 1; i >= a; --i) right[i - a] = nmax(right[i - a + 1], sqrt(nmax(x[i], 0.0)));
        int prev_deep = 0;
        for (idx_t i = a; i <= b; ++i) {
            const double w = sqrt(nmax(x[i], 0.0));
            left = nmax(left, w);
            const int deep = w < valley_depth * nmin(left, right[i - a]);
            if (i > a && deep && !prev_deep) valleys += 1.0;
            prev_deep = deep;
        }
        /* the piece's s* steps: running sums of time and of the first and second integrals */
        double t_acc = 0.0, S1_acc = 0.0, S2_acc = 0.0, rel1 = 0.0;
        for (idx_t k = a; k < b; ++k) {
            const double rel0 = s[k] - start_s;
            rel1 = s[k + 1] - start_s;
            const double dl = rel1 - rel0, v0 = sqrt(x[k]), v1 = sqrt(x[k + 1]);
            const double dt = 2.0 * dl / (v0 + v1), u = (x[k + 1] - x[k]) / (2.0 * dl);
            const double dt2 = dt * dt, dt3 = pow(dt, 3.0), dt4 = pow(dt, 4.0);
            const double t0 = t_acc, S1s = S1_acc, S2s = S2_acc;
            t_acc += dt;
            S1_acc += rel0 * dt + v0 * dt2 / 2.0 + u * dt3 / 6.0;
            S2_acc += S1s * dt + rel0 * dt2 / 2.0 + v0 * dt3 / 6.0 + u * dt4 / 24.0;
            const idx_t j = k - rests[0] + 2 * p + 1;            /* the step's segment */
            seg[j] = t0; seg[S + j] = rel0; seg[2 * S + j] = v0; seg[3 * S + j] = u;
            seg[4 * S + j] = S1s; seg[5 * S + j] = S2s;
            node_s[k - rests[0] + p] = start_s + rel0;
        }
        const double t_star = t_acc, tau = 0.5 * smoothing * t_star / (1.0 + valleys);
        const double dur = t_star + 2.0 * tau;
        dur_max = nmax(dur_max, dur);
        offs[p + 1] = offs[p] + dur;
        pieces[p] = tau; pieces[L + p] = dur; pieces[2 * L + p] = start_s; pieces[3 * L + p] = rel1;
        pieces[4 * L + p] = s[b]; pieces[5 * L + p] = t_star;
        const idx_t after = b - rests[0] - 1 + 2 * p + 2;       /* the rest after the piece */
        seg[after] = t_star; seg[S + after] = rel1; seg[4 * S + after] = S1_acc; seg[5 * S + after] = S2_acc;
        node_s[b - rests[0] + p] = start_s + rel1;
    }
    const double key_step = ldexp(1.0, (int)ceil(log2(4.0 * nmax(dur_max, 1e-300))));
    *key_step_out = key_step;
    for (idx_t p = 0; p < L; ++p) {
        const idx_t a = rests[p], b = rests[p + 1];
        const double base = offs[p] + pieces[p];                 /* s* delayed by tau */
        for (idx_t k = a; k < b; ++k) {
            const idx_t j = k - rests[0] + 2 * p + 1;
            seg_key[j] = L > 1 ? seg[j] + (double)p * key_step : seg[j];
            node_t[k - rests[0] + p] = base + seg[j];
        }
        const idx_t after = b - rests[0] - 1 + 2 * p + 2, before = after - (b - a) - 1;
        seg_key[after] = L > 1 ? seg[after] + (double)p * key_step : seg[after];
        seg_key[before] = ((double)p - 0.5) * key_step;
        node_t[b - rests[0] + p] = offs[p] + pieces[p] + pieces[5 * L + p];
    }
    seg_key[0] = -INFINITY;
}

/* sampling._interpolation_suspects: steps (n,) of lengths h whose cubic-Hermite interpolation is not
 * trustworthy. left, right (n, 6 dof): each step's end data (first, second and third derivatives)
 * from the left, then from the right; scale (3, dof): their largest magnitudes. Two mid-point
 * estimates of the first and second derivatives per joint, compared against tol times the joint's
 * scale, with the numpy code's formulas; bad (n,) 0/1. */
void gp_suspects(idx_t n, idx_t dof, const double *h, const double *left, const double *right,
                 const double *scale, double tol, uint8_t *bad)
{
    const double tiny = 1e-300;
    const idx_t w = 6 * dof;
    for (idx_t k = 0; k < n; ++k) {
        const double *L = left + k * w, *R = right + k * w, hk = h[k];
        int flag = 0;
        for (idx_t j = 0; j < dof && !flag; ++j) {
            const double a0 = L[3 * dof + j], b0 = L[4 * dof + j], c0 = L[5 * dof + j];
            const double b1 = R[dof + j], c1 = R[2 * dof + j];
            const double mid1a = 0.5 * (L[3 * dof + j] + R[j]) + hk * (L[4 * dof + j] - R[dof + j]) / 8.0;
            const double mid1b = 0.5 * (L[4 * dof + j] + R[dof + j]) + hk * (L[5 * dof + j] - R[2 * dof + j]) / 8.0;
            const double mid2a = a0 + hk * ((((13.0 / 32.0) * b0 + (11.0 / 192.0) * hk * c0) + (3.0 / 32.0) * b1)
                                            - (5.0 / 192.0) * hk * c1);
            const double mid2b = b0 + hk * (3.0 * c0 + c1) / 8.0;
            const double lim_a = tol * (scale[j] + tiny), lim_b = tol * ((scale[dof + j] + scale[j]) + tiny);
            if (fabs(mid1a - mid2a) > lim_a || fabs(mid1b - mid2b) > lim_b) flag = 1;
        }
        bad[k] = (uint8_t)flag;
    }
}

/* sampling.PathSamples.coef: per step of nodes s (n + 1,), the cubic Hermite coefficients of the first
 * and second derivatives in r = s - s_k, from the one-sided values and slopes at both ends (aR, bR,
 * cR leaving node k; aL, bL, cL arriving at node k + 1; each (n + 1, dof)); out (8, dof, n): rows 0-3
 * the first derivative, 4-7 the second, the numpy code's formulas. */
void gp_hermite_coef(idx_t n, idx_t dof, const double *s, const double *aL, const double *aR, const double *bL,
                     const double *bR, const double *cL, const double *cR, double *out)
{
    const idx_t plane = dof * n;
    for (int g = 0; g < 2; ++g) {
        const double *V0 = g ? bR : aR, *M0 = g ? cR : bR, *V1 = g ? bL : aL, *M1 = g ? cL : bL;
        double *o = out + 4 * g * plane;
        for (idx_t j = 0; j < dof; ++j)
            for (idx_t k = 0; k < n; ++k) {
                const double h = s[k + 1] - s[k];
                const double v0 = V0[k * dof + j], m0 = M0[k * dof + j];
                const double v1 = V1[(k + 1) * dof + j], m1 = M1[(k + 1) * dof + j];
                const double slope = (v1 - v0) / h;
                const idx_t at = j * n + k;
                o[at] = v0;
                o[plane + at] = m0;
                o[2 * plane + at] = (3.0 * slope - 2.0 * m0 - m1) / h;
                o[3 * plane + at] = (m0 + m1 - 2.0 * slope) / (h * h);
            }
    }
}

/* sampling.PathSamples.refined: the n steps of nodes s (n + 1,) each split into `factor` equal
 * parts, q' and q'' at the new nodes cubic Hermite (coef (8, dof, n) as in gp_hermite_ratios), the
 * one-sided values aL, aR, bL, bR (n + 1, dof) kept at the old nodes. Outputs s_out (m,) and
 * aL_out, aR_out, bL_out, bR_out (m, dof), m = n factor + 1. */
void gp_refine(idx_t n, idx_t dof, idx_t factor, const double *s, const double *aL, const double *aR,
               const double *bL, const double *bR, const double *coef, double *s_out, double *aL_out,
               double *aR_out, double *bL_out, double *bR_out)
{
    const idx_t plane = dof * n;
    for (idx_t k = 0; k <= n; ++k) {
        const idx_t o = k * factor;
        s_out[o] = s[k];
        for (idx_t j = 0; j < dof; ++j) {
            aL_out[o * dof + j] = aL[k * dof + j]; aR_out[o * dof + j] = aR[k * dof + j];
            bL_out[o * dof + j] = bL[k * dof + j]; bR_out[o * dof + j] = bR[k * dof + j];
        }
        if (k == n) break;
        const double h = s[k + 1] - s[k];
        for (idx_t i = 1; i < factor; ++i) {
            const double extra = s[k] + h * ((double)i / (double)factor), r = extra - s[k];
            s_out[o + i] = extra;
            for (idx_t j = 0; j < dof; ++j) {
                double a, b;
                hermite(coef + j * n + k, plane, r, &a, &b);
                const idx_t at = (o + i) * dof + j;
                aL_out[at] = aR_out[at] = a;
                bL_out[at] = bR_out[at] = b;
            }
        }
    }
}

/* Per sample (s, sd, sdd[, sddd]) the largest ratios over the joints of |q' sd| / vmax,
 * |q' sdd + q'' sd^2| / amax and (when coef3 is not NULL) |q' sddd + 3 q'' sd sdd + q''' sd^3| / jmax,
 * each taken as a product with the limit's reciprocal (inv_vmax ...: a division per joint and
 * sample cost a third of the kernel; the ratios differ from numpy's quotients by at most 1 ulp),
 * with q', q'' cubic Hermite on the steps of nodes (n + 1,): coef (8, dof, n) as
 * sampling.PathSamples.coef, coef3 (3, dof, n) as its coef3. */
void gp_hermite_ratios(idx_t m, const double *s, const double *sd, const double *sdd, const double *sddd,
                       idx_t n, const double *nodes, idx_t dof, const double *coef, const double *coef3,
                       const double *inv_vmax, const double *inv_amax, const double *inv_jmax,
                       double *rv_out, double *ra_out, double *rj_out)
{
    const idx_t plane = dof * n;
    idx_t hint = 0;
    for (idx_t i = 0; i < m; ++i) {
        const idx_t k = clampi(upper_hint(nodes, n + 1, s[i], &hint) - 1, 0, n - 1);
        const double r = s[i] - nodes[k], v = sd[i], acc = sdd[i], v2 = v * v;
        double rv = -INFINITY, ra = -INFINITY, rj = -INFINITY;
        for (idx_t j = 0; j < dof; ++j) {
            double a, b;
            hermite(coef + j * n + k, plane, r, &a, &b);
            double x = fabs(a * v) * inv_vmax[j];
            if (x > rv || isnan(x)) rv = x;
            x = fabs(a * acc + b * v2) * inv_amax[j];
            if (x > ra || isnan(x)) ra = x;
            if (coef3) {
                const double *c3 = coef3 + j * n + k;
                double q3 = c3[2 * plane];
                q3 *= r; q3 += c3[plane]; q3 *= r; q3 += c3[0];
                x = fabs(a * sddd[i] + 3.0 * b * (v * acc) + q3 * (v2 * v)) * inv_jmax[j];
                if (x > rj || isnan(x)) rj = x;
            }
        }
        rv_out[i] = rv;
        ra_out[i] = ra;
        if (coef3) rj_out[i] = rj;
    }
}

/* hi (n + 1,): hi_n = 0, hi_k = min(static_k, min_j A_kj hi_{k+1} + B_kj); A, B (n, R). */
void gp_backward_pass(idx_t n, idx_t R, const double *A, const double *B, const double *st, double *hi)
{
    double h = 0.0;
    hi[n] = 0.0;
    for (idx_t k = n - 1; k >= 0; --k) {
        double best = st[k];
        const double *a = A + k * R, *b = B + k * R;
        for (idx_t j = 0; j < R; ++j) {
            double v = a[j] * h + b[j];
            if (v < best) best = v;
        }
        h = best;
        hi[k] = h;
    }
}

/* x (n + 1,): x_0 = 0, u_k = min((hi_{k+1} - x_k) / (2 h_k), min_j alpha_kj x_k + d_kj),
 * x_{k+1} = min(max(x_k + 2 h_k u_k, 0), hi_{k+1}); alpha, d (n, R), two_h (n,), hi (n + 1,). */
void gp_forward_pass(idx_t n, idx_t R, const double *alpha, const double *d, const double *two_h,
                     const double *hi, double *x)
{
    double xk = 0.0;
    x[0] = 0.0;
    for (idx_t k = 0; k < n; ++k) {
        double u = (hi[k + 1] - xk) / two_h[k];
        const double *al = alpha + k * R, *dk = d + k * R;
        for (idx_t j = 0; j < R; ++j) {
            double v = al[j] * xk + dk[j];
            if (v < u) u = v;
        }
        xk = nmin(nmax(xk + two_h[k] * u, 0.0), hi[k + 1]);
        x[k + 1] = xk;
    }
}

/* The constraint rows of topp.topp on the nodes s (n + 1,) with one-sided q', q'' (aL, aR, bL, bR,
 * each (n + 1, dof)), limits vmax, amax (dof,), x_max (n + 1,) or NULL, stop (n + 1,) (nonzero: a
 * corner). Per step k, the R = 2 dof acceleration rows |ra u + rb x_k| <= rl become
 * alpha x + c <= u <= alpha x + d; outputs alpha, d, A, B (n, R), the static bound on x_k (n,)
 * and 2 h_k (n,), with the same formulas, masks and order of operations as topp.topp. */
void gp_topp_rows(idx_t n, idx_t dof, const double *s, const double *aL, const double *aR, const double *bL,
                  const double *bR, const double *vmax, const double *amax, const double *x_max,
                  const int64_t *stop, double *alpha, double *d, double *A, double *B, double *st, double *two_h)
{
    const idx_t R = 2 * dof;
    double top_v = 0.0, top_a = 0.0;
    for (idx_t i = 0; i < (n + 1) * dof; ++i) {
        double v = nmax(fabs(aL[i]), fabs(aR[i]));
        if (v > top_v || isnan(v)) top_v = v;
    }
    for (idx_t k = 0; k < n; ++k) {
        const double dl = s[k + 1] - s[k];
        for (idx_t j = 0; j < dof; ++j) {
            double a0 = fabs(aR[k * dof + j]);
            double a1 = fabs(aL[(k + 1) * dof + j] + 2.0 * dl * bL[(k + 1) * dof + j]);
            if (a0 > top_a || isnan(a0)) top_a = a0;
            if (a1 > top_a || isnan(a1)) top_a = a1;
        }
    }
    const double eps_v = 1e-12 * fmax(top_v, 1e-300), eps_a = 1e-12 * fmax(top_a, 1e-300);
    for (idx_t k = 0; k < n; ++k) {
        /* velocity bound at node k: min over joints of (vmax / |q'|)^2, capped by x_max */
        double xv = INFINITY;
        for (idx_t j = 0; j < dof; ++j) {
            double a = nmax(fabs(aL[k * dof + j]), fabs(aR[k * dof + j]));
            if (a > eps_v) {
                double r = vmax[j] / a;
                r = r * r;
                if (r < xv) xv = r;
            }
        }
        if (x_max) xv = nmin(xv, x_max[k]);
        const double dl = s[k + 1] - s[k];
        two_h[k] = 2.0 * dl;
        double *al = alpha + k * R, *dk = d + k * R, *Ak = A + k * R, *Bk = B + k * R;
        double xz = INFINITY, xl = INFINITY, xp = INFINITY;
        for (idx_t j = 0; j < R; ++j) {
            const idx_t jj = j % dof;
            double ra, rb;
            if (j < dof) { ra = aR[k * dof + jj]; rb = bR[k * dof + jj]; }
            else { ra = aL[(k + 1) * dof + jj] + 2.0 * dl * bL[(k + 1) * dof + jj]; rb = bL[(k + 1) * dof + jj]; }
            const double rl = amax[jj], absa = fabs(ra);
            const int moving = absa > eps_a;
            double c;
            if (moving) {
                al[j] = -rb / ra;
                dk[j] = rl / absa;
                c = -rl / absa;
            } else {
                double absb = fabs(rb);
                if (absb > 0) { double z = rl / absb; if (z < xz) xz = z; }
                al[j] = 0.0;
                dk[j] = INFINITY;
                c = -INFINITY;
            }
            const double coef = -1.0 / (2.0 * dl) - al[j];
            if (moving && coef > 0) { double z = dk[j] / coef; if (z < xl) xl = z; }
            const double den = 1.0 + 2.0 * dl * al[j];
            if (moving && den > 0) { Ak[j] = 1.0 / den; Bk[j] = -2.0 * dl * c / den; }
            else { Ak[j] = 0.0; Bk[j] = INFINITY; }
        }
        for (idx_t i = 0; i < R; ++i)
            for (idx_t j = i + 1; j < R; ++j) {
                double z = (dk[i] + dk[j]) / fabs(al[i] - al[j]);
                if (z < xp || isnan(z)) xp = nmin(xp, z);
            }
        double v = nmin(nmin(nmin(xv, xz), nmin(xp, xl)), 1e12);
        st[k] = stop[k] ? 0.0 : nmax(v, 0.0);
    }
}

/* Sorted, each once (checks.distinct_times), in place, of n values made of sorted runs already
 * merged (round-off may leave neighbours out of order: an insertion sort puts them back). Returns
 * the count. */
static idx_t sort_distinct(double *a, idx_t n)
{
    for (idx_t i = 1; i < n; ++i) {
        const double x = a[i];
        idx_t j = i;
        while (j > 0 && a[j - 1] > x) { a[j] = a[j - 1]; --j; }
        a[j] = x;
    }
    idx_t k = 0;
    for (idx_t i = 0; i < n; ++i)
        if (k == 0 || a[i] > a[k - 1]) a[k++] = a[i];
    return k;
}

/* a (na,) and b (nb,), both sorted, merged into out (ties: a first). Returns na + nb. */
static idx_t merge(const double *a, idx_t na, const double *b, idx_t nb, double *out)
{
    idx_t i = 0, j = 0, k = 0;
    while (i < na && j < nb) out[k++] = (b[j] < a[i]) ? b[j++] : a[i++];
    while (i < na) out[k++] = a[i++];
    while (j < nb) out[k++] = b[j++];
    return k;
}

/* np.interp(x, xp, fp) for xp (n >= 2,) sorted (ties allowed): numpy's cases and formula. */
static double interp(double x, const double *xp, const double *fp, idx_t n, idx_t *hint)
{
    if (isnan(x)) return x;
    if (x < xp[0]) return fp[0];
    if (x >= xp[n - 1]) return fp[n - 1];
    const idx_t j = upper_hint(xp, n, x, hint) - 1;       /* xp[j] <= x < xp[j + 1] */
    if (x == xp[j]) return fp[j];
    const double slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j]);
    double r = slope * (x - xp[j]) + fp[j];
    if (isnan(r)) {
        r = slope * (x - xp[j + 1]) + fp[j + 1];
        if (isnan(r) && fp[j] == fp[j + 1]) r = fp[j];
    }
    return r;
}

/* A check grid into t: m uniform times on [0, duration] (np.linspace), the times np.interp(us,
 * xp, fp) (n_us, nx entries; us and xp sorted) and the sorted extra (ne,), sorted, each once.
 * tmp: m + n_us + ne doubles. Returns the count. */
static idx_t merged_grid(idx_t m, double duration, idx_t n_us, const double *us, idx_t nx, const double *xp,
                         const double *fp, idx_t ne, const double *extra, double *tmp, double *t)
{
    double *grid = tmp, *at = tmp + m;
    const double step = duration / (double)(m - 1);
    for (idx_t i = 0; i < m; ++i) grid[i] = (double)i * step + 0.0;
    grid[m - 1] = duration;
    idx_t hint = 0;
    for (idx_t i = 0; i < n_us; ++i) at[i] = interp(us[i], xp, fp, nx, &hint);
    /* merged into t, then with the extra (not in tmp) back into tmp, and copied to t */
    idx_t M = merge(grid, m, at, n_us, t);
    M = merge(t, M, extra, ne, tmp);
    for (idx_t i = 0; i < M; ++i) t[i] = tmp[i];
    return sort_distinct(t, M);
}

/* The smoothed law's dense check (smooth_check.check_law): the grid (m uniform times on [0,
 * duration], the rests offs (L + 1,) when L > 1, the times np.interp(us, node_s, node_t) at which
 * it passes us (n_us,); sorted, each once), the law there (tables as gp_piecewise_evaluate) and
 * the ratios of gp_hermite_ratios without the jerk. scratch: m + n_us + L + 1 doubles. out (6 or
 * more, cap = m + n_us + L + 1): rows t, s, sd, sdd, rv, ra. Returns the number of samples. */
idx_t gp_piecewise_check(idx_t m, idx_t n_us, const double *us, idx_t nn, const double *node_s,
                         const double *node_t, idx_t L, const double *offs, const double *pieces, double key_step,
                         idx_t S, const double *seg_key, const double *seg, idx_t n, const double *nodes, idx_t dof,
                         const double *coef, const double *inv_vmax, const double *inv_amax, double *scratch,
                         double *out)
{
    const idx_t cap = m + n_us + L + 1;
    const idx_t M = merged_grid(m, offs[L], n_us, us, nn, node_s, node_t, L > 1 ? L + 1 : 0, offs, scratch, out);
    double *row[6];
    for (int r = 0; r < 6; ++r) row[r] = out + r * cap;
    gp_piecewise_evaluate(M, row[0], L, offs, pieces, key_step, S, seg_key, seg, row[1], row[2], row[3], NULL);
    gp_hermite_ratios(M, row[1], row[2], row[3], NULL, n, nodes, dof, coef, NULL, inv_vmax, inv_amax, NULL,
                      row[4], row[5], NULL);
    return M;
}

/* The dense check grid of a box-filtered law (box_check.BoxCheck._dense): m uniform times on [0,
 * duration]; the times at which the law passes us (n_us,) (BoxLaw.times_at); inside the gaps
 * between its jerk events (BoxLaw.jerk_events), with full three samples each (at 0.01, 0.5, 0.99
 * of the gap), else the middles evenly strided to at most max_inside (the width search's grid);
 * sorted, each once, into t (cap = m + n_us + (full ? 3 (2 K + 3 L) : max_inside)). The law's
 * tables as gp_box_evaluate. scratch: 6 K + 5 L + 3 + 2 cap doubles (K = first[L] steps). Returns
 * the count. */
static idx_t search_grid(idx_t m, idx_t n_us, const double *us, idx_t max_inside, idx_t full, idx_t L,
                         const double *offs, const double *width, const double *ends, const idx_t *first,
                         const double *t0, const double *s0, double *scratch, double *t)
{
    const idx_t K = first[L], cap = m + n_us + (full ? 3 * (2 * K + 3 * L) : max_inside);
    const double duration = offs[L];
    double *ev = scratch, *A = ev + 2 * K + 3 * L + 1, *B = A + K + 1, *xp = B + K + 1, *fp = xp + K + L;
    double *grid = fp + K + L, *tmp = grid + cap;
    /* the jerk events: per piece s*'s step starts and end, and the same delayed by the window */
    idx_t ne = 0;
    for (idx_t p = 0; p < L; ++p) {
        const idx_t f = first[p], np1 = first[p + 1] - f + 1;
        for (idx_t k = 0; k < np1; ++k) {
            A[k] = offs[p] + (k < np1 - 1 ? t0[f + k] : ends[p]);
            B[k] = A[k] + width[p];
        }
        ev[ne++] = offs[p];
        ne += merge(A, np1, B, np1, ev + ne);
    }
    ev[ne++] = offs[L];
    ne = sort_distinct(ev, ne);
    /* the grid: uniform times, then the times at us, then the middles of the events' gaps */
    idx_t nx = 0;
    for (idx_t p = 0; p < L; ++p) {
        const idx_t f = first[p], np1 = first[p + 1] - f + 1;
        const double t_shift = offs[p] + 0.5 * width[p], s_start = ends[3 * L + p];
        for (idx_t k = 0; k < np1; ++k, ++nx) {
            xp[nx] = s_start + (k < np1 - 1 ? s0[f + k] : ends[L + p]);
            fp[nx] = t_shift + (k < np1 - 1 ? t0[f + k] : ends[p]);
        }
    }
    idx_t gaps = ne - 1 > 0 ? ne - 1 : 0, ni = 0;
    double *inside = grid;
    if (full) {
        for (idx_t k = 0; k < gaps; ++k) {
            const double g = ev[k + 1] - ev[k];
            inside[ni++] = ev[k] + 0.01 * g;
            inside[ni++] = ev[k] + 0.5 * g;
            inside[ni++] = ev[k] + 0.99 * g;
        }
    } else {
        idx_t stride = (gaps + max_inside - 1) / max_inside;
        if (stride < 1) stride = 1;
        for (idx_t k = 0; k < gaps; k += stride) inside[ni++] = ev[k] + 0.5 * (ev[k + 1] - ev[k]);
    }
    return merged_grid(m, duration, n_us, us, nx, xp, fp, ni, inside, tmp, t);
}

/* search_grid of a box-filtered law, the law there and its ratios to the limits. The law's tables
 * as gp_box_evaluate, the path's and the limits as gp_hermite_ratios (with the jerk); scratch as
 * search_grid. out (8 or more, cap): rows t, s, sd, sdd, sddd, rv, ra, rj. Returns the number of
 * samples. */
idx_t gp_box_search_grid(idx_t m, idx_t n_us, const double *us, idx_t max_inside, idx_t full,
                         idx_t L, const double *offs, const double *width, const double *ends,
                         const idx_t *first, const double *t0, const double *s0, const double *v0,
                         const double *u, const double *S1, idx_t n, const double *nodes, idx_t dof,
                         const double *coef, const double *coef3, const double *inv_vmax,
                         const double *inv_amax, const double *inv_jmax, double *scratch, double *out)
{
    const idx_t K = first[L], cap = m + n_us + (full ? 3 * (2 * K + 3 * L) : max_inside);
    const idx_t M = search_grid(m, n_us, us, max_inside, full, L, offs, width, ends, first, t0, s0, scratch, out);
    double *row[8];
    for (int r = 0; r < 8; ++r) row[r] = out + r * cap;
    gp_box_evaluate(M, row[0], L, offs, width, ends, first, t0, s0, v0, u, S1, row[1], row[2], row[3], row[4]);
    gp_hermite_ratios(M, row[1], row[2], row[3], row[4], n, nodes, dof, coef, coef3, inv_vmax, inv_amax, inv_jmax,
                      row[5], row[6], row[7]);
    return M;
}

/* The width search's check of the box-filtered law of window width (L,) on the pieces' s* (ends,
 * first, t0 ... S1 as gp_box_evaluate): its offsets (offs[i + 1] = offs[i] + (T*_i + width_i), as
 * build_box_law), then over search_grid the largest ratios to the limits, in blocks of samples.
 * The blocks are taken from the one at the fraction origin of the duration on, then from the start
 * (where the last check peaked: a longer law is seen to be longer sooner). Stops after the first
 * block where one of them exceeds its bound (bound (3,): bounds on rv, ra, rj; INFINITY: never).
 * out (5,): largest rv, ra, rj (over the samples seen), duration, the fraction of the duration at
 * which max(rv, sqrt(ra), cbrt(rj)) peaked. When it did not stop, the nc breakpoints at s = cross
 * (nc,) (sorted; q' or q'' jumps there) are checked too, as box_check.BoxCheck.ratios does: each
 * crossing time interpolated between the grid samples around it, the law there, and the exact
 * one-sided derivatives sides_a, sides_b, sides_c (2 nc, dof: left values, then right) against
 * vmax, amax, jmax (the limits themselves), by gp_point_ratios. scratch: L + 1 + search_grid's +
 * 4 cap + 5 nc doubles. Returns 1 when it stopped early, else 0. */
#define SEARCH_BLOCK 64
int64_t gp_box_search_max(idx_t m, idx_t n_us, const double *us, idx_t max_inside, idx_t L, const double *width,
                          const double *ends, const idx_t *first, const double *t0, const double *s0,
                          const double *v0, const double *u, const double *S1, idx_t n, const double *nodes,
                          idx_t dof, const double *coef, const double *coef3, const double *inv_vmax,
                          const double *inv_amax, const double *inv_jmax, const double *bound, double origin,
                          idx_t nc, const double *cross, const double *sides_a, const double *sides_b,
                          const double *sides_c, const double *vmax, const double *amax, const double *jmax,
                          double *scratch, double *out)
{
    const idx_t K = first[L], cap = m + n_us + max_inside;
    double *offs = scratch, *grid_scratch = offs + L + 1;
    double *t = grid_scratch + 6 * K + 5 * L + 3 + 2 * cap, *s_all = t + cap, *tc = s_all + cap;
    offs[0] = 0.0;
    for (idx_t p = 0; p < L; ++p) offs[p + 1] = offs[p] + (ends[p] + width[p]);
    const idx_t M = search_grid(m, n_us, us, max_inside, 0, L, offs, width, ends, first, t0, s0, grid_scratch, t);
    double rv = -INFINITY, ra = -INFINITY, rj = -INFINITY;
    idx_t peak[3] = {0, 0, 0}, seen = 0;
    int64_t stopped = 0;
    const idx_t blocks = (M + SEARCH_BLOCK - 1) / SEARCH_BLOCK;
    const idx_t first_block = clampi(lower(t, M, origin * offs[L]) / SEARCH_BLOCK, 0, blocks - 1);
    for (idx_t q = 0; q < blocks; ++q) {
        const idx_t i = ((first_block + q) % blocks) * SEARCH_BLOCK;
        const idx_t b = M - i < SEARCH_BLOCK ? M - i : SEARCH_BLOCK;
        double s[SEARCH_BLOCK], sd[SEARCH_BLOCK], sdd[SEARCH_BLOCK], sddd[SEARCH_BLOCK];
        double v[SEARCH_BLOCK], a[SEARCH_BLOCK], j[SEARCH_BLOCK];
        gp_box_evaluate(b, t + i, L, offs, width, ends, first, t0, s0, v0, u, S1, s, sd, sdd, sddd);
        gp_hermite_ratios(b, s, sd, sdd, sddd, n, nodes, dof, coef, coef3, inv_vmax, inv_amax, inv_jmax, v, a, j);
        for (idx_t k = 0; k < b; ++k) {
            s_all[i + k] = s[k];
            if (!(v[k] <= rv)) { rv = nmax(rv, v[k]); peak[0] = i + k; }
            if (!(a[k] <= ra)) { ra = nmax(ra, a[k]); peak[1] = i + k; }
            if (!(j[k] <= rj)) { rj = nmax(rj, j[k]); peak[2] = i + k; }
        }
        seen += b;
        if (rv > bound[0] || ra > bound[1] || rj > bound[2]) { stopped = seen < M; break; }
    }
    if (!stopped && nc > 0 && M > 1) {
        /* jerk._crossing_times (newton=0): the bracket on the grid, linear in s there */
        double *sb = tc + nc, *sdb = sb + nc, *sddb = sdb + nc, *sdddb = sddb + nc, r[3], q[3];
        for (idx_t k = 0; k < nc; ++k) {
            const idx_t jx = clampi(lower(s_all, M, cross[k]), 1, M - 1);
            const double lo = t[jx - 1], hi = t[jx], ds = s_all[jx] - s_all[jx - 1];
            tc[k] = lo + (hi - lo) * (ds > 0 ? clampd((cross[k] - s_all[jx - 1]) / ds, 0.0, 1.0) : 0.5);
        }
        gp_box_evaluate(nc, tc, L, offs, width, ends, first, t0, s0, v0, u, S1, sb, sdb, sddb, sdddb);
        gp_point_ratios(nc, dof, sides_a, sides_b, sides_c, sdb, sddb, sdddb, vmax, amax, jmax, r);
        gp_point_ratios(nc, dof, sides_a + nc * dof, sides_b + nc * dof, sides_c + nc * dof, sdb, sddb, sdddb,
                        vmax, amax, jmax, q);
        for (int e = 0; e < 3; ++e) r[e] = nmax(r[e], q[e]);
        /* Python's max(previous, value): the value only when larger */
        if (r[0] > rv) rv = r[0];
        if (r[1] > ra) ra = r[1];
        if (r[2] > rj) rj = r[2];
    }
    const double need[3] = {rv, sqrt(ra), cbrt(rj)};
    int top = 0;
    for (int r = 1; r < 3; ++r) if (need[r] > need[top]) top = r;
    out[0] = rv; out[1] = ra; out[2] = rj; out[3] = offs[L];
    out[4] = M > 0 && offs[L] > 0.0 ? t[peak[top]] / offs[L] : 0.0;
    return stopped;
}

/* The columns of two sample blocks merged by their first row, sorted in each (ties: a first), as a
 * stable argsort of the concatenated first rows orders them: a's first na columns (rows of lda
 * doubles), then b's first nb (rows of ldb); out (rows, na + nb). scratch: nb + 1 indices (b is
 * the short block: each row is copied in runs of a). */
void gp_merge_columns(idx_t rows, idx_t na, idx_t lda, const double *a, idx_t nb, idx_t ldb, const double *b,
                      double *out, idx_t *scratch)
{
    const idx_t n = na + nb;
    idx_t *before = scratch;          /* columns of a before b[j]: those <= b[j] (ties: a first) */
    idx_t hint = 0;
    for (idx_t j = 0; j < nb; ++j) before[j] = upper_hint(a, na, b[j], &hint);
    before[nb] = na;
    for (idx_t r = 0; r < rows; ++r) {
        const double *ar = a + r * lda, *br = b + r * ldb;
        double *o = out + r * n;
        idx_t from = 0;
        for (idx_t j = 0; j <= nb; ++j) {
            const idx_t to = before[j] > from ? before[j] : from;
            memcpy(o, ar + from, (size_t)(to - from) * sizeof(double));
            o += to - from;
            from = to;
            if (j < nb) *o++ = br[j];
        }
    }
}

/* The largest |q' sd| / vmax, |q' sdd + q'' sd^2| / amax and |q' sddd + 3 q'' sd sdd + q''' sd^3|
 * / jmax over K samples with exact derivatives a, b, c (K, dof) and sd, sdd, sddd (K,): out (3,),
 * with the formulas, order of operations and NaN propagation of box_check.BoxCheck._max_ratios. */
void gp_point_ratios(idx_t K, idx_t dof, const double *a, const double *b, const double *c, const double *sd,
                     const double *sdd, const double *sddd, const double *vmax, const double *amax,
                     const double *jmax, double *out)
{
    double rv = -INFINITY, ra = -INFINITY, rj = -INFINITY;
    for (idx_t k = 0; k < K; ++k) {
        const double v = sd[k], acc = sdd[k], jk = sddd[k], v2 = v * v, v3 = pow(v, 3.0);
        for (idx_t j = 0; j < dof; ++j) {
            const double ak = a[k * dof + j], bk = b[k * dof + j], ck = c[k * dof + j];
            rv = nmax(rv, fabs(ak * v) / vmax[j]);
            ra = nmax(ra, fabs(ak * acc + bk * v2) / amax[j]);
            rj = nmax(rj, fabs(ak * jk + 3.0 * bk * v * acc + ck * v3) / jmax[j]);
        }
    }
    out[0] = rv; out[1] = ra; out[2] = rj;
}

/* checks.peak_samples: at sorted times t (n,) with speed factors need (n,), the local peaks
 * (need[i] >= both neighbours), the k highest of them (ties: the later one, as the last k of a
 * stable ascending argsort), and around each, the inner `per` of per + 2 points evenly spaced
 * from -spacing to +spacing (np.linspace) added to its time and clipped to [0, duration]; all of
 * them sorted into out (at most k per). scratch: 2 k doubles. Returns the count. */
idx_t gp_peak_samples(idx_t n, const double *t, const double *need, double spacing, double duration, idx_t k,
                      idx_t per, double *scratch, double *out)
{
    double *top_need = scratch, *top_idx = scratch + k;      /* ascending by (need, index) */
    idx_t count = 0;
    for (idx_t i = 1; i + 1 < n; ++i) {
        const double v = need[i];
        if (!(v >= need[i - 1] && v >= need[i + 1])) continue;
        /* (v, i) beats the smallest kept when v >= it: i is the later index */
        if (count == k && !(v >= top_need[0])) continue;
        idx_t pos;
        if (count < k) {
            pos = count++;
        } else {
            for (idx_t j = 1; j < k; ++j) { top_need[j - 1] = top_need[j]; top_idx[j - 1] = top_idx[j]; }
            pos = k - 1;
        }
        while (pos > 0 && !(top_need[pos - 1] <= v)) {       /* v above a kept one: insert below it */
            top_need[pos] = top_need[pos - 1];
            top_idx[pos] = top_idx[pos - 1];
            --pos;
        }
        top_need[pos] = v;
        top_idx[pos] = (double)i;
    }
    const double start = -spacing, step = (spacing - start) / (double)(per + 1);
    idx_t m = 0;
    for (idx_t c = 0; c < count; ++c) {
        const double tc = t[(idx_t)top_idx[c]];
        for (idx_t j = 1; j <= per; ++j) out[m++] = clampd(tc + ((double)j * step + start), 0.0, duration);
    }
    for (idx_t i = 1; i < m; ++i) {                       /* insertion sort: at most k per values */
        const double x = out[i];
        idx_t j = i;
        while (j > 0 && out[j - 1] > x) { out[j] = out[j - 1]; --j; }
        out[j] = x;
    }
    return m;
}
