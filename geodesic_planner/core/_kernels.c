/* Compiled kernels of the library's hot loops (loaded with ctypes by core/compiled.py).
 *
 * Each function does, sample by sample, what the numpy code beside it does on whole arrays (same
 * formulas, same order of operations): the numpy code stays the fallback and the reference the
 * tests compare with. Arrays are C-contiguous float64; sizes are int64. No allocation, no Python.
 *
 *   gp_frames              core.kinematics.Chain frames and generators (forward kinematics)
 *   gp_polynomials         core.polynomials.evaluate_polynomials (the paths' quintic splines)
 *   gp_jacobian_rate       core.redundant.RedundantEquations.rate (dJ[u], the redundant solver)
 *   gp_geodesic_acceleration  core.geodesic.GeodesicEquations.acceleration (the geodesic equations)
 *   gp_geodesic_jerk       core.geodesic.GeodesicEquations.jerk (q'' and q''' along a geodesic)
 *   gp_capsule_distances   core.capsules.capsule_distances (sphere and capsule bodies' distances)
 *   gp_build_piecewise     smoothing.build_piecewise_law (the smoothed law's tables)
 *   gp_piecewise_evaluate  smoothing.PiecewiseLaw.evaluate (the smoothed law s(t) and derivatives)
 *   gp_piecewise_check     smooth_check.check_law: the smoothed law's check grid, the law there
 *                          and its ratios, in one call
 *   gp_box_evaluate        box_filter.BoxLaw.evaluate (the box-filtered law of the jerk law)
 *   gp_suspects            sampling._interpolation_suspects (where the samples need bisecting)
 *   gp_hermite_coef        sampling.PathSamples.coef (the cubic Hermite coefficients of the steps)
 *   gp_refine              sampling.PathSamples.refined (finer steps, q' and q'' cubic Hermite)
 *   gp_hermite_ratios      sampling.PathSamples.interpolate_t (+ third_derivative_t) and the
 *                          per-sample ratios to the velocity, acceleration (and jerk) limits
 *   gp_backward_pass       topp: hi_k = min(static_k, min_j A_kj hi_{k+1} + B_kj), hi_n = 0
 *   gp_forward_pass        topp: the greedy forward pass
 *   gp_topp_rows           topp: the passes' constraint rows and static bounds
 *   gp_box_search_grid     box_check.BoxCheck._dense: the dense or the width search's check grid of a
 *                          box-filtered law, the law there and its ratios, in one call
 *   gp_merge_columns       box_check.BoxCheck._dense: two sample blocks merged by time (stable argsort)
 *   gp_point_ratios        box_check.BoxCheck._max_ratios: the largest ratios of exact samples
 *   gp_peak_samples        checks.peak_samples (more check times around the highest peaks)
 *   gp_box_search_max      the same check's largest ratios only, from the window, stopping early
 *                          once they exceed bounds (jerk._best_width)
 *
 * This file holds the core's kernels and the module init, which only makes the extension importable
 * (so that setuptools builds it with the package; it defines no Python functions); the time laws'
 * kernels are in _kernels_timing.c, the shared helpers in _kernels.h.
 */
#include <Python.h>

#include "_kernels.h"

/* Serial-chain kinematics (kinematics.Chain._frames and _generators) at q (N, dof): fixed (dof + 1,
 * 4, 4) the constant transforms with every joint axis folded onto z, prismatic (dof,) nonzero for
 * a prismatic joint. Outputs (each may be NULL but T): Tj (N, dof, 4, 4) base -> joint frame before
 * its motion, T (N, 4, 4) base -> tool, X (N, dof, 4, 4) the spatial twist matrices (dT/dq_k = X_k T). */
void gp_frames(idx_t N, idx_t dof, const double *q, const double *fixed, const int64_t *prismatic,
               double *Tj, double *T_out, double *X)
{
    for (idx_t n = 0; n < N; ++n) {
        double T[16], MF[16], R[16];
        for (int a = 0; a < 16; ++a) T[a] = fixed[a];
        for (idx_t i = 0; i < dof; ++i) {
            const double *F = fixed + 16 * (i + 1);
            const double qi = q[n * dof + i];
            if (Tj) for (int a = 0; a < 16; ++a) Tj[(n * dof + i) * 16 + a] = T[a];
            if (X) {
                double *x = X + (n * dof + i) * 16;
                const double u0 = T[2], u1 = T[6], u2 = T[10];          /* the joint axis (z) */
                const double p0 = T[3], p1 = T[7], p2 = T[11];          /* its origin */
                for (int a = 0; a < 16; ++a) x[a] = 0.0;
                if (prismatic[i]) {
                    x[3] = u0; x[7] = u1; x[11] = u2;
                } else {
                    x[1] = -u2; x[2] = u1; x[4] = u2; x[6] = -u0; x[8] = -u1; x[9] = u0;
                    x[3] = p1 * u2 - p2 * u1; x[7] = p2 * u0 - p0 * u2; x[11] = p0 * u1 - p1 * u0;
                }
            }
            /* M_i F_{i+1}: a rotation about z (rows 0 and 1) or a translation along z (row 2) */
            for (int a = 0; a < 16; ++a) MF[a] = F[a];
            if (prismatic[i]) {
                for (int c = 0; c < 4; ++c) MF[8 + c] += qi * F[12 + c];
            } else {
                const double co = cos(qi), si = sin(qi);
                for (int c = 0; c < 4; ++c) {
                    MF[c] = co * F[c] - si * F[4 + c];
                    MF[4 + c] = si * F[c] + co * F[4 + c];
                }
            }
            for (int r = 0; r < 4; ++r)
                for (int c = 0; c < 4; ++c)
                    R[4 * r + c] = T[4 * r] * MF[c] + T[4 * r + 1] * MF[4 + c] + T[4 * r + 2] * MF[8 + c]
                                   + T[4 * r + 3] * MF[12 + c];
            for (int a = 0; a < 16; ++a) T[a] = R[a];
        }
        for (int a = 0; a < 16; ++a) T_out[n * 16 + a] = T[a];
    }
}

/* out = A B for 4 x 4 matrices (row-major). */
static inline void mul4(const double *A, const double *B, double *out)
{
    for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c)
            out[4 * r + c] = A[4 * r] * B[c] + A[4 * r + 1] * B[4 + c] + A[4 * r + 2] * B[8 + c] + A[4 * r + 3] * B[12 + c];
}

/* G = L L^T in place (L in the lower triangle) for G (dof, dof) symmetric; 0 when G is not
 * numerically positive definite. */
static int cholesky(double *G, idx_t dof)
{
    for (idx_t j = 0; j < dof; ++j) {
        double d = G[j * dof + j];
        for (idx_t k = 0; k < j; ++k) d -= G[j * dof + k] * G[j * dof + k];
        if (!(d > 0.0) || !isfinite(d)) return 0;
        d = sqrt(d);
        G[j * dof + j] = d;
        for (idx_t i = j + 1; i < dof; ++i) {
            double s = G[i * dof + j];
            for (idx_t k = 0; k < j; ++k) s -= G[i * dof + k] * G[j * dof + k];
            G[i * dof + j] = s / d;
        }
    }
    return 1;
}

/* x = G^-1 b from the factor of cholesky (two triangular solves). */
static void cholesky_solve(const double *G, idx_t dof, const double *b, double *x)
{
    for (idx_t i = 0; i < dof; ++i) {
        double s = b[i];
        for (idx_t k = 0; k < i; ++k) s -= G[i * dof + k] * x[k];
        x[i] = s / G[i * dof + i];
    }
    for (idx_t i = dof - 1; i >= 0; --i) {
        double s = x[i];
        for (idx_t k = i + 1; k < dof; ++k) s -= G[k * dof + i] * x[k];
        x[i] = s / G[i * dof + i];
    }
}

/* Piecewise quintics (polynomials.evaluate_polynomials): segment i of knots t (N,) has coefficients
 * c[i] (6, dof) in ascending powers of tau = x - t[i]. At times x (m,): position and derivatives up
 * to order (<= 3) into out (order + 1, m, dof), by the same Horner steps as the numpy code. */
void gp_polynomials(idx_t m, const double *x, idx_t N, const double *t, const double *c, idx_t dof,
                    idx_t order, double *out)
{
    idx_t hint = 0;
    const idx_t plane = m * dof;
    for (idx_t i = 0; i < m; ++i) {
        const idx_t seg = clampi(upper_hint(t, N, x[i], &hint) - 1, 0, N - 2);
        const double tau = x[i] - t[seg];
        const double *cs = c + seg * 6 * dof;
        for (idx_t j = 0; j < dof; ++j) {
            const double c5 = cs[5 * dof + j];
            double pos = c5, vel = 5.0 * c5, acc = 20.0 * c5, jerk = 60.0 * c5;
            for (int k = 4; k >= 0; --k) {
                const double ck = cs[k * dof + j];
                pos = pos * tau + ck;
                if (k >= 1) vel = vel * tau + k * ck;
                if (k >= 2) acc = acc * tau + k * (k - 1) * ck;
                if (k >= 3) jerk = jerk * tau + k * (k - 1) * (k - 2) * ck;
            }
            double *o = out + i * dof + j;
            o[0] = pos;
            if (order >= 1) o[plane] = vel;
            if (order >= 2) o[2 * plane] = acc;
            if (order >= 3) o[3 * plane] = jerk;
        }
    }
}

/* redundant.RedundantEquations.rate: the directional derivative dJ[u] (6, dof) of the geometric
 * Jacobian, for B batch elements each with twist matrices X (dof, 4, 4) (kinematics generators),
 * tool pose T (4, 4) and direction u (dof,); out (B, 6, dof), rows [dv; dw]. Joint k's twist turns
 * with the joints before it: dw_k = a x w_k, dv_k = a x v_k - w_k x b + w_k x dp + dw_k x p, with
 * a, b the sums of w_j u_j, v_j u_j over j < k, p the tool position and dp = A x p + V (A, V the
 * sums over all joints). */
void gp_jacobian_rate(idx_t B, idx_t dof, const double *X, const double *T, const double *u, double *out)
{
    for (idx_t e = 0; e < B; ++e) {
        const double *Xe = X + e * dof * 16, *Te = T + e * 16, *ue = u + e * dof;
        double *o = out + e * 6 * dof;
        const double p[3] = {Te[3], Te[7], Te[11]};
        double A[3] = {0.0, 0.0, 0.0}, V[3] = {0.0, 0.0, 0.0};
        for (idx_t k = 0; k < dof; ++k) {
            const double *x = Xe + 16 * k;
            A[0] += x[9] * ue[k]; A[1] += x[2] * ue[k]; A[2] += x[4] * ue[k];
            V[0] += x[3] * ue[k]; V[1] += x[7] * ue[k]; V[2] += x[11] * ue[k];
        }
        const double dp[3] = {A[1] * p[2] - A[2] * p[1] + V[0], A[2] * p[0] - A[0] * p[2] + V[1],
                              A[0] * p[1] - A[1] * p[0] + V[2]};
        double a[3] = {0.0, 0.0, 0.0}, b[3] = {0.0, 0.0, 0.0};
        for (idx_t k = 0; k < dof; ++k) {
            const double *x = Xe + 16 * k;
            const double w[3] = {x[9], x[2], x[4]}, v[3] = {x[3], x[7], x[11]};
            const double dw[3] = {a[1] * w[2] - a[2] * w[1], a[2] * w[0] - a[0] * w[2], a[0] * w[1] - a[1] * w[0]};
            for (int i = 0; i < 3; ++i) {
                const int i1 = (i + 1) % 3, i2 = (i + 2) % 3;
                const double dv = (a[i1] * v[i2] - a[i2] * v[i1]) - (w[i1] * b[i2] - w[i2] * b[i1])
                                  + (w[i1] * dp[i2] - w[i2] * dp[i1]) + (dw[i1] * p[i2] - dw[i2] * p[i1]);
                o[i * dof + k] = dv;
                o[(3 + i) * dof + k] = dw[i];
            }
            for (int i = 0; i < 3; ++i) { a[i] += w[i] * ue[k]; b[i] += v[i] * ue[k]; }
        }
    }
}

/* The geodesic acceleration a = -G^-1 b (geodesic.GeodesicEquations.acceleration) at N samples, from
 * the generators X (N, dof, 4, 4) and tool poses T (N, 4, 4) at q, the velocities v (N, dof), the
 * metric's weights mask (4, 4) on dT and its epsilon: Y_k = X_k T, G_ij = <Y_i, Y_j>_mask + eps
 * delta_ij, W_k = X_k v_k, P_k = (W_1 + .. + W_k) - W_k, H = (sum_k (W_k + 2 P_k) W_k) T,
 * b_i = <Y_i, H>_mask. G is solved by Cholesky; scratch holds dof (16 + dof + 1) + 64 doubles.
 * Returns 0, or 1 + the first sample where G is not numerically positive definite (a is then
 * incomplete: the caller takes its numpy path, which tells a singular metric apart). */
int64_t gp_geodesic_acceleration(idx_t N, idx_t dof, const double *X, const double *T, const double *v,
                                 const double *mask, double eps, double *a, double *scratch)
{
    double *Y = scratch, *G = Y + 16 * dof, *b = G + dof * dof, *Cs = b + dof;   /* Cs: 16 C, 16 W, 16 S, 16 H */
    double *Cm = Cs, *Wm = Cs + 16, *S = Cs + 32, *H = Cs + 48;
    for (idx_t n = 0; n < N; ++n) {
        const double *Xn = X + n * dof * 16, *Tn = T + n * 16, *vn = v + n * dof;
        for (idx_t k = 0; k < dof; ++k)
            for (int r = 0; r < 4; ++r)
                for (int c = 0; c < 4; ++c) {
                    const double *x = Xn + 16 * k + 4 * r;
                    Y[16 * k + 4 * r + c] = x[0] * Tn[c] + x[1] * Tn[4 + c] + x[2] * Tn[8 + c] + x[3] * Tn[12 + c];
                }
        for (idx_t i = 0; i < dof; ++i)
            for (idx_t j = 0; j <= i; ++j) {
                double g = 0.0;
                for (int e = 0; e < 16; ++e) g += mask[e] * Y[16 * i + e] * Y[16 * j + e];
                G[i * dof + j] = G[j * dof + i] = g + (i == j ? eps : 0.0);
            }
        for (int e = 0; e < 16; ++e) { Cm[e] = 0.0; S[e] = 0.0; }
        for (idx_t k = 0; k < dof; ++k) {
            const double *x = Xn + 16 * k;
            for (int e = 0; e < 16; ++e) { Wm[e] = x[e] * vn[k]; Cm[e] += Wm[e]; }
            double L[16];                                       /* W_k + 2 P_k, P_k = C_k - W_k */
            for (int e = 0; e < 16; ++e) L[e] = Wm[e] + 2.0 * (Cm[e] - Wm[e]);
            for (int r = 0; r < 4; ++r)
                for (int c = 0; c < 4; ++c)
                    S[4 * r + c] += L[4 * r] * Wm[c] + L[4 * r + 1] * Wm[4 + c] + L[4 * r + 2] * Wm[8 + c]
                                    + L[4 * r + 3] * Wm[12 + c];
        }
        for (int r = 0; r < 4; ++r)
            for (int c = 0; c < 4; ++c)
                H[4 * r + c] = S[4 * r] * Tn[c] + S[4 * r + 1] * Tn[4 + c] + S[4 * r + 2] * Tn[8 + c]
                               + S[4 * r + 3] * Tn[12 + c];
        for (idx_t i = 0; i < dof; ++i) {
            double s = 0.0;
            for (int e = 0; e < 16; ++e) s += mask[e] * Y[16 * i + e] * H[e];
            b[i] = -s;
        }
        if (!cholesky(G, dof)) return n + 1;
        cholesky_solve(G, dof, b, a + n * dof);
    }
    return 0;
}

/* The geodesic acceleration q'' and its s-derivative q''' (core.geodesic.GeodesicEquations.jerk),
 * each (N, dof) into a and jerk, from X, T, v, mask and eps as gp_geodesic_acceleration, by the
 * same terms as its numpy code: G q''' = -(<D_k, f''>_W + <Y_k, 3 sum_j D_j a_j + T3>_W) with
 * D_k = (C_k X_k + X_k (C_n - C_k)) T, f'' = sum_k Y_k a_k + H, H = 2 c2 T, T3 = 6 c3 T (c1, c2,
 * c3 the Taylor coefficients of the product of the joints' exponentials, kinematics.taylor3).
 * scratch: dof (50 + dof) doubles. Returns 0, or 1 + the first sample whose G is not numerically
 * positive definite (its outputs from there on are not written). */
int64_t gp_geodesic_jerk(idx_t N, idx_t dof, const double *X, const double *T, const double *v,
                         const double *mask, double eps, double *a, double *jerk, double *scratch)
{
    double *Y = scratch, *Cs = Y + 16 * dof, *D = Cs + 16 * dof, *G = D + 16 * dof, *b = G + dof * dof;
    double *r = b + dof;
    for (idx_t n = 0; n < N; ++n) {
        const double *Xn = X + n * dof * 16, *Tn = T + n * 16, *vn = v + n * dof;
        for (idx_t k = 0; k < dof; ++k) mul4(Xn + 16 * k, Tn, Y + 16 * k);
        for (idx_t i = 0; i < dof; ++i)
            for (idx_t j = 0; j <= i; ++j) {
                double g = 0.0;
                for (int e = 0; e < 16; ++e) g += mask[e] * Y[16 * i + e] * Y[16 * j + e];
                G[i * dof + j] = G[j * dof + i] = g + (i == j ? eps : 0.0);
            }
        double c1[16] = {0}, c2[16] = {0}, c3[16] = {0}, C[16] = {0}, W[16], W2[16], P[16], Q[16];
        for (idx_t k = 0; k < dof; ++k) {
            for (int e = 0; e < 16; ++e) { W[e] = Xn[16 * k + e] * vn[k]; C[e] += W[e]; Cs[16 * k + e] = C[e]; }
            mul4(W, W, W2);
            mul4(c2, W, P);                   /* c3 += c2 W + c1 W^2 / 2 + W^3 / 6 */
            for (int e = 0; e < 16; ++e) c3[e] += P[e];
            mul4(c1, W2, P);
            mul4(W2, W, Q);
            for (int e = 0; e < 16; ++e) c3[e] += P[e] / 2.0 + Q[e] / 6.0;
            mul4(c1, W, P);                   /* c2 += c1 W + W^2 / 2 */
            for (int e = 0; e < 16; ++e) { c2[e] += P[e] + W2[e] / 2.0; c1[e] += W[e]; }
        }
        double H[16], T3[16], Da[16] = {0}, F[16];
        mul4(c2, Tn, H);
        mul4(c3, Tn, T3);
        for (int e = 0; e < 16; ++e) { H[e] *= 2.0; T3[e] *= 6.0; }
        for (idx_t i = 0; i < dof; ++i) {
            double s = 0.0;
            for (int e = 0; e < 16; ++e) s += mask[e] * Y[16 * i + e] * H[e];
            b[i] = -s;
        }
        if (!cholesky(G, dof)) return n + 1;
        double *an = a + n * dof;
        cholesky_solve(G, dof, b, an);
        for (int e = 0; e < 16; ++e) F[e] = H[e];
        for (idx_t k = 0; k < dof; ++k) {       /* D_k = (C_k X_k + X_k (C_n - C_k)) T */
            const double *Ck = Cs + 16 * k, *Cn = Cs + 16 * (dof - 1), *Xk = Xn + 16 * k;
            double R[16];
            mul4(Ck, Xk, P);
            for (int e = 0; e < 16; ++e) R[e] = Cn[e] - Ck[e];
            mul4(Xk, R, Q);
            for (int e = 0; e < 16; ++e) P[e] += Q[e];
            mul4(P, Tn, D + 16 * k);
            for (int e = 0; e < 16; ++e) { Da[e] += D[16 * k + e] * an[k]; F[e] += Y[16 * k + e] * an[k]; }
        }
        for (idx_t k = 0; k < dof; ++k) {
            double s = 0.0;
            for (int e = 0; e < 16; ++e)
                s += D[16 * k + e] * (F[e] * mask[e]) + mask[e] * Y[16 * k + e] * (3.0 * Da[e] + T3[e]);
            r[k] = -s;
        }
        cholesky_solve(G, dof, r, jerk + n * dof);
    }
    return 0;
}

static inline double dot3(const double *x, const double *y) { return x[0] * y[0] + x[1] * y[1] + x[2] * y[2]; }

static inline double clamp01(double x) { return x < 0.0 ? 0.0 : (x > 1.0 ? 1.0 : x); }

/* Signed distances of capsule (or sphere: half length 0) bodies ia[k], ib[k] at configuration n[k]:
 * their segments' distance (Ericson 5.1.9, as capsules.segment_distances) less both radii.
 * P: (N, bodies, 4, 4) body frames, the capsule's axis along z. */
void gp_capsule_distances(idx_t K, idx_t bodies, const double *P, const double *half, const double *radius,
                          const int64_t *n, const int64_t *ia, const int64_t *ib, double *out)
{
    const double eps = 1e-24;
    for (idx_t k = 0; k < K; ++k) {
        const double *Fa = P + 16 * (n[k] * bodies + ia[k]), *Fb = P + 16 * (n[k] * bodies + ib[k]);
        const double ha = half[ia[k]], hb = half[ib[k]];
        double a0[3], b0[3], d1[3], d2[3], r[3];
        for (int i = 0; i < 3; ++i) {
            const double ua = ha * Fa[4 * i + 2], ub = hb * Fb[4 * i + 2];
            a0[i] = Fa[4 * i + 3] - ua;
            b0[i] = Fb[4 * i + 3] - ub;
            d1[i] = (Fa[4 * i + 3] + ua) - a0[i];
            d2[i] = (Fb[4 * i + 3] + ub) - b0[i];
            r[i] = a0[i] - b0[i];
        }
        const double a = dot3(d1, d1), e = dot3(d2, d2), f = dot3(d2, r), c = dot3(d1, r), b = dot3(d1, d2);
        const int point_a = a <= eps, point_b = e <= eps;
        const double safe_a = point_a ? 1.0 : a, safe_e = point_b ? 1.0 : e;
        const double denom = a * e - b * b;
        double s = denom > 0.0 ? clamp01((b * f - c * e) / denom) : 0.0;
        if (point_b) s = clamp01(-c / safe_a);
        if (point_a) s = 0.0;
        const double t = point_b ? 0.0 : (b * s + f) / safe_e;
        const double tc = clamp01(t);
        if (tc != t && !point_a) s = clamp01((b * tc - c) / safe_a);
        double d2sum = 0.0;
        for (int i = 0; i < 3; ++i) {
            const double diff = (a0[i] + s * d1[i]) - (b0[i] + tc * d2[i]);
            d2sum += diff * diff;
        }
        out[k] = sqrt(d2sum) - radius[ia[k]] - radius[ib[k]];
    }
}

static struct PyModuleDef kernels_module = {
    PyModuleDef_HEAD_INIT, .m_name = "_kernels",
    .m_doc = "Compiled kernels of the library (see core/compiled.py).", .m_size = -1};

PyMODINIT_FUNC PyInit__kernels(void) { return PyModule_Create(&kernels_module); }
