/* A plain, hand-written C closed-loop RK4 lap: the hardware-limit reference of bench_lap.py.
 *
 * The same closed loop as casadrone's compiled lap (casadrone/simulate.py, model.py,
 * guidance.py), written out by hand: 16-state quadrotor (rigid body, quadratic body drag,
 * first-order thrust lag), line-of-sight guidance with the braking speed profile, reference
 * shaping, LQR-I with saturation and anti-windup, one RK4 step per controller sample. It flies a
 * given number of samples and stores the state and command of each; no failure checks, no
 * logging of references or acceleration, no indices. J^-1 is inverted once per lap.
 *
 * Inputs are casadrone's own vectors: p (airframe, PARAM_NAMES order), x0, u0 (trim), K (4 x 20,
 * column-major), g (track_vector), n_route. Build: cc -O2 -shared -fPIC plain_lap.c -lm.
 */
#include <math.h>

#define NX 16

typedef struct {
  double m, Jinv[9], J[9], r[12], s[4], kappa, cda[3], rho, K, tau, grav;
} Params;

static void rotation(double phi, double th, double psi, double R[9]) {
  double cph = cos(phi), sph = sin(phi), cth = cos(th), sth = sin(th);
  double cps = cos(psi), sps = sin(psi);
  R[0] = cps * cth; R[1] = cps * sth * sph - sps * cph; R[2] = cps * sth * cph + sps * sph;
  R[3] = sps * cth; R[4] = sps * sth * sph + cps * cph; R[5] = sps * sth * cph - cps * sph;
  R[6] = -sth;      R[7] = cth * sph;                   R[8] = cth * cph;
}

static void model(const Params* P, const double* x, const double* u, double* xd) {
  double R[9], v[3] = {x[3], x[4], x[5]}, w[3] = {x[6], x[7], x[8]}, T[4];
  double Tsum = 0, tq[3] = {0, 0, 0}, Jw[3], rhs[3];
  int i, j;
  rotation(x[9], x[10], x[11], R);
  for (i = 0; i < 4; ++i) { T[i] = x[12 + i]; Tsum += T[i]; }
  for (i = 0; i < 3; ++i) xd[i] = R[3 * i] * v[0] + R[3 * i + 1] * v[1] + R[3 * i + 2] * v[2];
  /* m v' = -m w x v + sum T e_z + R^T (0, 0, -m g) - 1/2 rho CdA |v| v */
  double f[3];
  for (i = 0; i < 3; ++i) f[i] = -P->m * P->grav * R[6 + i] - 0.5 * P->rho * P->cda[i] * fabs(v[i]) * v[i];
  f[2] += Tsum;
  xd[3] = f[0] / P->m - (w[1] * v[2] - w[2] * v[1]);
  xd[4] = f[1] / P->m - (w[2] * v[0] - w[0] * v[2]);
  xd[5] = f[2] / P->m - (w[0] * v[1] - w[1] * v[0]);
  /* J w' = tau - w x J w; tau = sum r_i x (0, 0, T_i) + s_i kappa T_i e_z */
  for (i = 0; i < 4; ++i) {
    tq[0] += P->r[3 * i + 1] * T[i];
    tq[1] -= P->r[3 * i] * T[i];
    tq[2] += P->s[i] * P->kappa * T[i];
  }
  for (i = 0; i < 3; ++i) Jw[i] = P->J[3 * i] * w[0] + P->J[3 * i + 1] * w[1] + P->J[3 * i + 2] * w[2];
  rhs[0] = tq[0] - (w[1] * Jw[2] - w[2] * Jw[1]);
  rhs[1] = tq[1] - (w[2] * Jw[0] - w[0] * Jw[2]);
  rhs[2] = tq[2] - (w[0] * Jw[1] - w[1] * Jw[0]);
  for (i = 0; i < 3; ++i) {
    xd[6 + i] = 0;
    for (j = 0; j < 3; ++j) xd[6 + i] += P->Jinv[3 * i + j] * rhs[j];
  }
  /* Euler rates: W(phi, theta) w */
  double cph = cos(x[9]), sph = sin(x[9]), cth = cos(x[10]), tth = tan(x[10]);
  xd[9] = w[0] + sph * tth * w[1] + cph * tth * w[2];
  xd[10] = cph * w[1] - sph * w[2];
  xd[11] = sph / cth * w[1] + cph / cth * w[2];
  for (i = 0; i < 4; ++i) xd[12 + i] = (P->K * u[i] - T[i]) / P->tau;
}

static double clamp(double a, double lo, double hi) { return a < lo ? lo : (a > hi ? hi : a); }

static int active(double seg, int ns) {
  int k;
  for (k = 0; k < ns; ++k)
    if (seg <= k + 0.5) return k;
  return ns - 1;
}

/* Line-of-sight guidance: p_ref, v_ref, psi_ref and the segment after switching. */
static double guidance(const double* pos, double seg, const double* g, int n, double* p_ref,
                       double* v_ref, double* psi_ref) {
  int ns = n - 1, k, i;
  const double *heads = g + 3 * n, *caps = heads + ns, *ends = caps + ns, *tail = ends + ns;
  double r_acc = tail[0], look = tail[1], brake = tail[2];
  const double *a, *b;
  double t[3], L, s, d2 = 0;
  k = active(seg, ns);
  a = g + 3 * k; b = a + 3;
  for (i = 0; i < 3; ++i) t[i] = b[i] - a[i];
  L = sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
  s = ((pos[0] - a[0]) * t[0] + (pos[1] - a[1]) * t[1] + (pos[2] - a[2]) * t[2]) / L;
  for (i = 0; i < 3; ++i) d2 += (pos[i] - b[i]) * (pos[i] - b[i]);
  double seg_next = seg + ((seg < ns - 0.5) && (sqrt(d2) < r_acc || s >= L) ? 1 : 0);
  int done = seg_next > ns - 0.5;
  k = active(seg_next, ns);
  a = g + 3 * k; b = a + 3;
  for (i = 0; i < 3; ++i) t[i] = b[i] - a[i];
  L = sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
  for (i = 0; i < 3; ++i) t[i] /= L;
  s = clamp((pos[0] - a[0]) * t[0] + (pos[1] - a[1]) * t[1] + (pos[2] - a[2]) * t[2], 0, L);
  double ahead = fmin(s + look, L), los[3], nl = 0;
  for (i = 0; i < 3; ++i) { los[i] = a[i] + ahead * t[i] - pos[i]; nl += los[i] * los[i]; }
  double v_mag = fmin(caps[k], sqrt(ends[k] * ends[k] + 2 * brake * (L - s)));
  nl = fmax(sqrt(nl), 1e-6);
  for (i = 0; i < 3; ++i) {
    p_ref[i] = done ? b[i] : a[i] + s * t[i];
    v_ref[i] = done ? 0.0 : v_mag * los[i] / nl;
  }
  *psi_ref = heads[k];
  return seg_next;
}

/* Fly n samples from state x (16) with controller state c (8); store X (n x 16), U (n x 4). */
int plain_lap(const double* p, const double* x0, const double* u0, const double* K,
              const double* g, int n_route, double Ts, long long n, double* x, double* c,
              double* X, double* U) {
  Params P;
  int i, j;
  long long k;
  int gsize = 3 * n_route + 3 * (n_route - 1) + 6;
  double a_max = g[gsize - 1], max_pos = g[gsize - 2], max_yaw = g[gsize - 3];
  P.m = p[0];
  double Jm[9] = {p[1], p[4], p[5], p[4], p[2], p[6], p[5], p[6], p[3]};
  for (i = 0; i < 9; ++i) P.J[i] = Jm[i];
  double det = Jm[0] * (Jm[4] * Jm[8] - Jm[5] * Jm[7]) - Jm[1] * (Jm[3] * Jm[8] - Jm[5] * Jm[6])
             + Jm[2] * (Jm[3] * Jm[7] - Jm[4] * Jm[6]);
  P.Jinv[0] = (Jm[4] * Jm[8] - Jm[5] * Jm[7]) / det; P.Jinv[1] = (Jm[2] * Jm[7] - Jm[1] * Jm[8]) / det;
  P.Jinv[2] = (Jm[1] * Jm[5] - Jm[2] * Jm[4]) / det; P.Jinv[3] = (Jm[5] * Jm[6] - Jm[3] * Jm[8]) / det;
  P.Jinv[4] = (Jm[0] * Jm[8] - Jm[2] * Jm[6]) / det; P.Jinv[5] = (Jm[2] * Jm[3] - Jm[0] * Jm[5]) / det;
  P.Jinv[6] = (Jm[3] * Jm[7] - Jm[4] * Jm[6]) / det; P.Jinv[7] = (Jm[1] * Jm[6] - Jm[0] * Jm[7]) / det;
  P.Jinv[8] = (Jm[0] * Jm[4] - Jm[1] * Jm[3]) / det;
  for (i = 0; i < 12; ++i) P.r[i] = p[7 + i];
  for (i = 0; i < 4; ++i) P.s[i] = p[19 + i];
  P.kappa = p[23];
  for (i = 0; i < 3; ++i) P.cda[i] = p[24 + i];
  P.rho = p[27]; P.K = p[28]; P.tau = p[29]; P.grav = p[30];

  for (k = 0; k < n; ++k) {
    double p_ref[3], v_ref[3], psi_ref, R[9], dx[20], u[4], u_raw[4], e_pos[3], e_psi;
    for (i = 0; i < NX; ++i) X[k * NX + i] = x[i];
    double seg_next = guidance(x, c[4], g, n_route, p_ref, v_ref, &psi_ref);
    /* reference shaping: rate-limited velocity reference */
    double dv[3], ndv = 0, vf[3];
    for (i = 0; i < 3; ++i) { dv[i] = v_ref[i] - c[5 + i]; ndv += dv[i] * dv[i]; }
    double step = fmin(1.0, a_max * Ts / fmax(sqrt(ndv), 1e-9));
    for (i = 0; i < 3; ++i) vf[i] = c[5 + i] + step * dv[i];
    /* errors in the heading frame, LQR-I, saturation, anti-windup */
    double cps = cos(x[11]), sps = sin(x[11]), d[3];
    for (i = 0; i < 3; ++i) d[i] = x[i] - p_ref[i];
    e_pos[0] = clamp(cps * d[0] + sps * d[1], -max_pos, max_pos);
    e_pos[1] = clamp(-sps * d[0] + cps * d[1], -max_pos, max_pos);
    e_pos[2] = clamp(d[2], -max_pos, max_pos);
    rotation(x[9], x[10], x[11], R);
    double ang = x[11] - psi_ref;
    e_psi = clamp(atan2(sin(ang), cos(ang)), -max_yaw, max_yaw);
    for (i = 0; i < 3; ++i) {
      dx[i] = e_pos[i];
      dx[3 + i] = x[3 + i] - (R[i] * vf[0] + R[3 + i] * vf[1] + R[6 + i] * vf[2]);
      dx[6 + i] = x[6 + i];
    }
    dx[9] = x[9] - x0[9]; dx[10] = x[10] - x0[10]; dx[11] = e_psi;
    for (i = 0; i < 4; ++i) { dx[12 + i] = x[12 + i] - x0[12 + i]; dx[16 + i] = c[i]; }
    double sat = 0;
    for (i = 0; i < 4; ++i) {
      u_raw[i] = u0[i];
      for (j = 0; j < 20; ++j) u_raw[i] -= K[4 * j + i] * dx[j];
      u[i] = clamp(u_raw[i], 0.0, 1.0);
      sat += fabs(u_raw[i] - u[i]);
      U[k * 4 + i] = u[i];
    }
    if (!(sat > 0)) {
      for (i = 0; i < 3; ++i) c[i] += Ts * e_pos[i];
      c[3] += Ts * e_psi;
    }
    c[4] = seg_next;
    for (i = 0; i < 3; ++i) c[5 + i] = vf[i];
    /* RK4 plant over one sample */
    double k1[NX], k2[NX], k3[NX], k4[NX], xs[NX], h = Ts;
    model(&P, x, u, k1);
    for (i = 0; i < NX; ++i) xs[i] = x[i] + h / 2 * k1[i];
    model(&P, xs, u, k2);
    for (i = 0; i < NX; ++i) xs[i] = x[i] + h / 2 * k2[i];
    model(&P, xs, u, k3);
    for (i = 0; i < NX; ++i) xs[i] = x[i] + h * k3[i];
    model(&P, xs, u, k4);
    for (i = 0; i < NX; ++i) x[i] += h / 6 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]);
  }
  return 0;
}
