// The hot path of spline evaluation: one kernel per (dimensions, order, channels, storage, input,
// uniform spans), so that every loop has a compile-time trip count and the contraction works on
// whole vectors of contiguous coefficients. Written with GCC vector extensions; each kernel is
// compiled for x86-64-v4, x86-64-v3 and the baseline (target_clones).
//
// Per point:
// - prepare: the D parameters as one vector; for uniform spans, span index and local parameter
//   of all axes in a few vector instructions (else a binary search per axis); the d+1 non-zero
//   basis values of each axis by Horner on the per-span power form (no division).
// - contract: (17)/(18) nested. The last axis's P coefficients times C channels are contiguous:
//   a row of P*C values, one vector (float32: 16 lanes) or a few (float64: 4 lanes, and the
//   values left over in scalars so nothing past the row is read). For each (i, j) of axes 0, 1 the P rows of
//   axis 2 are summed with weights B_j into P accumulators, those with weights B_i into P more;
//   B_k folds them into one row and B_l with the channels gives the result, in registers.
//   For the 4D quadratic RGB radiance spline: 27 rows of 9 values, 243 + 81 + 27 + 9 useful
//   multiply-adds in 27 + 9 + 3 vector instructions (float32).
// - 16 points are prepared, then contracted, and directions are mapped to the disc a block at a
//   time in a vectorised loop of their own.
// Measured (bench_spline_eval, float64, one thread, about 3.7 GHz): the contraction of one point
// takes about 60 cycles from a block in L1 (it is bound by loads and multiply-adds), the
// preparation about 25, the map about 13.
#include "spline_kernels.h"

#include <algorithm>
#include <cfloat>
#include <ctime>
#include <cmath>
#include <cstdlib>
#include <string>

namespace bsgi::detail {

namespace {

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
// The wheel keeps the x86-64 baseline; the loader picks the best clone for the running CPU.
#define BSGI_CLONES __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#define BSGI_CLONES
#endif
#define BSGI_INLINE inline __attribute__((always_inline))
#define BSGI_LAMBDA_INLINE __attribute__((always_inline))
// Loops with compile-time trip counts are unrolled completely, so small arrays live in registers.
#define BSGI_UNROLL _Pragma("GCC unroll 64")

constexpr int ipow(int b, int e) { return e == 0 ? 1 : b * ipow(b, e - 1); }

// Span I (binary search for the last knot <= x among t_d .. t_last) and local parameter
// s = (x - t_I) / (t_{I+1} - t_I) of x, already in the domain. (Uniform spans take the vector
// path of prepare_uniform instead.)
template <int P>
BSGI_INLINE int find_span(const SplineLanes& l, int k, double x, double& s) {
    constexpr int d = P - 1;
    const double* t = l.knots[k];
    int lo = d, hi = l.last[k] + d;
    while (lo < hi) {
        const int mid = (lo + hi + 1) >> 1;
        if (t[mid] <= x) lo = mid;
        else hi = mid - 1;
    }
    s = (x - t[lo]) * l.inv_width[k][lo - d];
    return lo;
}

// GCC vector extensions: whole registers of the instruction set a kernel is compiled for (v4d:
// one AVX register, or a pair of SSE2 ones in the baseline version).
typedef double v4d __attribute__((vector_size(32)));
typedef float v4f __attribute__((vector_size(16)));
typedef float v8f __attribute__((vector_size(32)));
typedef float v16f __attribute__((vector_size(64)));

// Contraction arithmetic in the storage type, with WF float lanes (the register width of the
// instruction set the kernel is compiled for: 16 with AVX-512, 8 with AVX2, 4 with SSE2).
// Double (float64 coefficients): 4 lanes, and a row whose length is not a multiple of 4 ends
// with a load moved back to end at the row's end (overlapping the one before), so nothing past
// the coefficients is read. Float (float32 coefficients): whole registers, the last one may read
// past the row's end, which the storage allows (TensorSpline pads float32 coefficients with
// kFloat32Padding zeros). See the bound in tensor_spline.h for float arithmetic.
template <typename T, int WF>
struct Lanes;
template <int WF>
struct Lanes<double, WF> {
    using V = v4d;
    static constexpr int W = 4;
    static constexpr bool padded = false;
};
template <>
struct Lanes<float, 16> {
    using V = v16f;
    static constexpr int W = 16;
    static constexpr bool padded = true;
};
template <>
struct Lanes<float, 8> {
    using V = v8f;
    static constexpr int W = 8;
    static constexpr bool padded = true;
};
template <>
struct Lanes<float, 4> {
    using V = v4f;
    static constexpr int W = 4;
    static constexpr bool padded = true;
};

template <typename V, typename T>
BSGI_INLINE V load_vec(const T* p) {
    V v;
    __builtin_memcpy(&v, p, sizeof v);
    return v;
}

// Basis values (lanes 0..P-1) of one parameter on axis k; returns the offset of the first
// non-zero coefficient along the axis, in values.
template <int P>
BSGI_INLINE size_t axis_basis(const SplineLanes& l, int k, double x, v4d& b, bool& finite) {
    const bool ok = std::fabs(x) <= DBL_MAX;  // false for NaN and infinities
    finite &= ok;
    x = ok ? x : l.lo[k];
    x = std::min(std::max(x, l.lo[k]), l.hi[k]);  // clamp to the domain
    double s;
    const int span = find_span<P>(l, k, x, s);
    // Horner on the power form: rows of the table are P apart, lanes >= P unused (the table is
    // padded so that the last load stays inside it).
    const double* c = l.poly[k] + size_t(span - (P - 1)) * P * P;
    b = load_vec<v4d>(c + (P - 1) * P);
    BSGI_UNROLL
    for (int e = P - 2; e >= 0; --e) b = b * s + load_vec<v4d>(c + e * P);
    return size_t(span - (P - 1)) * l.stride[k];
}

// What the contraction of one point needs: its basis values and first coefficient.
template <int D, typename T>
struct Prepared {
    v4d b[D];  // basis values of each axis in lanes 0..P-1
    const T* block;
    bool finite;
};

typedef int v4si __attribute__((vector_size(16)));

// Uniform spans: span and local parameter of all parameters of a point (one lane per axis,
// D <= 4) in a few vector instructions.
template <int D, int P, typename T>
BSGI_INLINE Prepared<D, T> prepare_uniform(v4d x, const SplineLanes& u, const T* coeffs) {
    static_assert(D <= 4, "one lane per axis");
    Prepared<D, T> p;
    const v4d lo = load_vec<v4d>(u.lo), hi = load_vec<v4d>(u.hi);
    const auto ok = (x < 0 ? -x : x) <= DBL_MAX;  // false for NaN and infinities
    p.finite = (ok[0] & ok[1] & ok[2] & ok[3]) != 0;
    x = ok ? x : lo;
    x = x < lo ? lo : x;  // clamp to the domain
    x = x > hi ? hi : x;
    const v4d t = (x - lo) * load_vec<v4d>(u.inv_h);
    v4si j = __builtin_convertvector(t, v4si);
    const v4si last = load_vec<v4si>(u.last);
    j = j > last ? last : j;
    // On a knot t may land at s = 1 of the span on its left instead of s = 0 of the one on its
    // right: the same value up to rounding, the spline being continuous there.
    const v4d s = t - __builtin_convertvector(j, v4d);
    p.block = coeffs;
    BSGI_UNROLL
    for (int k = 0; k < D; ++k) {
        const double* c = u.poly[k] + size_t(j[k]) * P * P;
        v4d b = load_vec<v4d>(c + (P - 1) * P);
        BSGI_UNROLL
        for (int e = P - 2; e >= 0; --e) b = b * s[k] + load_vec<v4d>(c + e * P);
        p.b[k] = b;
        p.block += size_t(j[k]) * u.stride[k];
    }
    return p;
}

template <int D, int P, typename T>
BSGI_INLINE Prepared<D, T> prepare(v4d x, const SplineLanes& l, const T* coeffs) {
    Prepared<D, T> p;
    p.finite = true;
    p.block = coeffs;
    BSGI_UNROLL
    for (int k = 0; k < D; ++k) p.block += axis_basis<P>(l, k, x[k], p.b[k], p.finite);
    return p;
}

// Where the parameters of point i come from, as one vector built in registers (a round trip
// through memory would stall store forwarding): the rows of a (count x D) array ...
template <int D>
struct ParamSource {
    const double* params;
    BSGI_INLINE v4d operator()(size_t i) const {
        if constexpr (D == 4) {
            return load_vec<v4d>(params + 4 * i);
        } else {
            v4d x = {0, 0, 0, 0};
            BSGI_UNROLL
            for (int k = 0; k < D; ++k) x[k] = params[D * i + k];
            return x;
        }
    }
};

// ... or (u, v) and (alpha, beta) already mapped from the directions of a block of points.
struct MappedSource {
    const double* uv;
    const double *alpha, *beta;  // of points first, first + 1, ...
    size_t first;
    BSGI_INLINE v4d operator()(size_t i) const {
        return v4d{uv[2 * i], uv[2 * i + 1], alpha[i - first], beta[i - first]};
    }
};

// Broadcast of lane j of the basis values, in the arithmetic type.
template <typename V, typename T>
BSGI_INLINE V splat(const v4d& b, int j) {
    return V{} + T(b[j]);
}

// (17)/(18) as nested contractions with short independent chains: for each index i of axis 0
// and j of axis 1 (4D), the P rows of axis 2 (each row: the P coefficients of axis 3 times the
// channels, contiguous) are summed into P accumulators weighted by B_j, those into P more
// weighted by B_i; then B_k combines the P accumulators into one row, and B_l with the
// channels gives the result.
template <int D, int P, int C, typename T, int WF>
BSGI_INLINE void contract(const Prepared<D, T>& p, const size_t* stride, double* o) {
    static_assert(D == 2 || D == 4, "kernels exist for 2D and 4D");
    constexpr int L = P * C;  // values per row (last axis x channels, contiguous)
    using V = typename Lanes<T, WF>::V;
    constexpr int W = Lanes<T, WF>::W;
    constexpr bool padded = Lanes<T, WF>::padded;
    // A row is NV vectors of W values (see Lanes) and, unpadded, NT < W values left over, done in
    // scalars: scalar loads never straddle a cache line, where a vector load moved back to end at
    // the row's end mostly does (float64 rows of 9 values start every 24 bytes), at the cost of
    // two loads. Unpadded rows shorter than W are all scalars.
    constexpr int NV = padded ? (L + W - 1) / W : L / W;
    constexpr int NT = padded ? 0 : L - NV * W;
    constexpr int NTA = NT > 0 ? NT : 1;  // array sizes
    auto at = [](int v) constexpr { return W * v; };
    // The strides go through an empty asm per point: otherwise the compiler hoists the 27 x NV
    // row offsets out of the loop over points and, short of registers, reloads them from the
    // stack, a second load per row load (the contraction is bound by loads).
    size_t rs = stride[D - 2];
    asm volatile("" : "+r"(rs));
    if constexpr (NV == 0) {
        // Short rows (fewer values than lanes, float64): scalars.
        T row[L] = {};
        for (int g = 0; g < (D == 4 ? P * P : 1); ++g) {
            const int i = g / P, j = g % P;
            const T* q = p.block + (D == 4 ? i * stride[0] + j * stride[1] : 0);
            const T wg = D == 4 ? T(p.b[0][i] * p.b[1][j]) : T(1);
            BSGI_UNROLL
            for (int r = 0; r < P; ++r) {
                const T wr = wg * T(p.b[D - 2][r]);
                BSGI_UNROLL
                for (int e = 0; e < L; ++e) row[e] += wr * q[r * rs + e];
            }
        }
        BSGI_UNROLL
        for (int c = 0; c < C; ++c) {
            double v = 0;
            BSGI_UNROLL
            for (int l = 0; l < P; ++l) v += p.b[D - 1][l] * double(row[l * C + c]);
            o[c] = p.finite ? v : NAN;
        }
        return;
    } else {
        V acc[P][NV];
        T acct[P][NTA];
        if constexpr (D == 2) {
            BSGI_UNROLL
            for (int r = 0; r < P; ++r) {
                BSGI_UNROLL
                for (int v = 0; v < NV; ++v) acc[r][v] = load_vec<V>(p.block + r * rs + at(v));
                BSGI_UNROLL
                for (int t = 0; t < NT; ++t) acct[r][t] = p.block[r * rs + NV * W + t];
            }
        } else {
            size_t s0 = stride[0], s1 = stride[1];
            asm volatile("" : "+r"(s0), "+r"(s1));
            const T* pi = p.block;
            BSGI_UNROLL
            for (int i = 0; i < P; ++i, pi += s0) {
                V acc_i[P][NV];
                T acct_i[P][NTA];
                const T* pj = pi;
                BSGI_UNROLL
                for (int j = 0; j < P; ++j, pj += s1) {
                    const V bj = splat<V, T>(p.b[1], j);
                    const T bjt = T(p.b[1][j]);
                    BSGI_UNROLL
                    for (int r = 0; r < P; ++r) {
                        BSGI_UNROLL
                        for (int v = 0; v < NV; ++v) {
                            const V row = load_vec<V>(pj + r * rs + at(v));
                            acc_i[r][v] = j == 0 ? bj * row : acc_i[r][v] + bj * row;
                        }
                        BSGI_UNROLL
                        for (int t = 0; t < NT; ++t) {
                            const T x = pj[r * rs + NV * W + t];
                            acct_i[r][t] = j == 0 ? bjt * x : acct_i[r][t] + bjt * x;
                        }
                    }
                }
                const V bi = splat<V, T>(p.b[0], i);
                const T bit = T(p.b[0][i]);
                BSGI_UNROLL
                for (int r = 0; r < P; ++r) {
                    BSGI_UNROLL
                    for (int v = 0; v < NV; ++v) acc[r][v] = i == 0 ? bi * acc_i[r][v] : acc[r][v] + bi * acc_i[r][v];
                    BSGI_UNROLL
                    for (int t = 0; t < NT; ++t) acct[r][t] = i == 0 ? bit * acct_i[r][t] : acct[r][t] + bit * acct_i[r][t];
                }
            }
        }
        V sum[NV];
        BSGI_UNROLL
        for (int v = 0; v < NV; ++v) {
            sum[v] = splat<V, T>(p.b[D - 2], 0) * acc[0][v];
            BSGI_UNROLL
            for (int r = 1; r < P; ++r) sum[v] += splat<V, T>(p.b[D - 2], r) * acc[r][v];
        }
        T sumt[NTA];
        BSGI_UNROLL
        for (int t = 0; t < NT; ++t) {
            sumt[t] = T(p.b[D - 2][0]) * acct[0][t];
            BSGI_UNROLL
            for (int r = 1; r < P; ++r) sumt[t] += T(p.b[D - 2][r]) * acct[r][t];
        }
        if constexpr (padded && NV == 1 && W == 16) {
            // The row in one register: out_c = sum_l B_l sum[l C + c] by a lane-wise product and
            // P - 1 shifted adds. Lane e of the multiplier is B_{e / C} (lanes past the row are
            // never read).
            typedef int v16i __attribute__((vector_size(64)));
            const v4f bf = __builtin_convertvector(p.b[D - 1], v4f);
            const V b16 = {bf[0], bf[1], bf[2], bf[3]};
            constexpr v16i lane = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15};
            const V prod = sum[0] * __builtin_shuffle(b16, (lane / C) & 3);
            V out_c = prod;
            BSGI_UNROLL
            for (int l = 1; l < P; ++l) out_c += __builtin_shuffle(prod, (lane + l * C) & 15);
            BSGI_UNROLL
            for (int c = 0; c < C; ++c) o[c] = p.finite ? double(out_c[c]) : NAN;
        } else {
            T row[NV * W > L ? NV * W : L];
            BSGI_UNROLL
            for (int v = 0; v < NV; ++v)
                BSGI_UNROLL
                for (int e = 0; e < W; ++e) row[at(v) + e] = sum[v][e];
            BSGI_UNROLL
            for (int t = 0; t < NT; ++t) row[NV * W + t] = sumt[t];
            BSGI_UNROLL
            for (int c = 0; c < C; ++c) {
                double v = 0;
                BSGI_UNROLL
                for (int l = 0; l < P; ++l) v += p.b[D - 1][l] * double(row[l * C + c]);
                o[c] = p.finite ? v : NAN;
            }
        }
    }
}

template <int D, int P, int C, typename T, int WF, bool Uniform, typename Source>
BSGI_INLINE void evaluate_range(const Source& source, const SplineLanes& lanes, const T* coeffs, size_t begin, size_t end,
                                double* out) {
    if (begin >= end) return;
    // The spans and basis of a few points first, then their contractions: the dependency chain
    // of a point's preparation (parameter -> span -> table -> basis, and the block's address) is
    // then long done when its contraction starts, and the contractions' loads of the points after
    // it are independent of anything before.
    auto prep = [&](size_t i) BSGI_LAMBDA_INLINE {
        if constexpr (Uniform) return prepare_uniform<D, P, T>(source(i), lanes, coeffs);
        else return prepare<D, P, T>(source(i), lanes, coeffs);
    };
    constexpr size_t S = 16;
    Prepared<D, T> prepared[S];
    for (size_t first = begin; first < end; first += S) {
        const size_t n = std::min(end - first, S);
        for (size_t i = 0; i < n; ++i) prepared[i] = prep(first + i);
        for (size_t i = 0; i < n; ++i) contract<D, P, C, T, WF>(prepared[i], lanes.stride, out + (first + i) * C);
    }
}

// The inverse hemisphere map of up to kMapBlock directions, in loops of their own: copied apart by
// coordinate, the map's square roots and division are independent from point to point and
// vectorise (element-wise loop), instead of lengthening each point's chain. `map` should be a
// local copy, so that the compiler knows the stores cannot change it.
constexpr size_t kMapBlock = 256;
BSGI_INLINE void map_block(const HemisphereMap& map, const double* d, size_t n, double* alpha, double* beta) {
    double dx[kMapBlock], dy[kMapBlock], dz[kMapBlock];
    for (size_t i = 0; i < n; ++i) dx[i] = d[3 * i], dy[i] = d[3 * i + 1], dz[i] = d[3 * i + 2];
    for (size_t i = 0; i < n; ++i) {
        double ab[2];
        map.to_disc(dx[i], dy[i], dz[i], ab);
        alpha[i] = ab[0], beta[i] = ab[1];
    }
}

template <int D, int P, int C, typename T, bool Dirs, bool Uniform, int WF>
BSGI_INLINE void evaluate_points(const KernelArgs& args, size_t begin, size_t end, double* out) {
    static_assert(D >= 2 && D <= 4, "the last two axes are the rows and their accumulators");
    static_assert(P <= 4, "one vector of basis values per axis");
    // A local copy: the compiler then knows the output stores cannot change it.
    const SplineLanes lanes = *args.lanes;
    const T* const coeffs = static_cast<const T*>(args.coeffs);
    if constexpr (Dirs) {
        // A block of directions mapped first.
        double alpha[kMapBlock], beta[kMapBlock];
        const HemisphereMap map = *args.map;
        for (size_t first = begin; first < end; first += kMapBlock) {
            const size_t n = std::min(end - first, kMapBlock);
            map_block(map, args.dirs + 3 * first, n, alpha, beta);
            evaluate_range<D, P, C, T, WF, Uniform>(MappedSource{args.uv, alpha, beta, first}, lanes, coeffs, first,
                                                first + n, out);
        }
    } else {
        evaluate_range<D, P, C, T, WF, Uniform>(ParamSource<D>{args.params}, lanes, coeffs, begin, end, out);
    }
}

// One point: what evaluate_range does for each of its points, read straight from the spline's
// lanes (no copies to reload).
template <int D, int P, int C, typename T, bool Uniform, int WF>
BSGI_INLINE void evaluate_point(const SplineLanes& lanes, const void* coeffs, const double* x, double* out) {
    const v4d xv = ParamSource<D>{x}(0);
    const T* c = static_cast<const T*>(coeffs);
    if constexpr (Uniform) contract<D, P, C, T, WF>(prepare_uniform<D, P, T>(xv, lanes, c), lanes.stride, out);
    else contract<D, P, C, T, WF>(prepare<D, P, T>(xv, lanes, c), lanes.stride, out);
}

// Each kernel is compiled three times, for x86-64-v4 (AVX-512: 16 float lanes), x86-64-v3 (AVX2
// and FMA: 8) and the baseline (SSE2: 4); find_kernel picks one for the running CPU, so the wheel
// keeps the x86-64 baseline. (target_clones would compile one source for all three, but the
// float lane count has to follow the register width.)
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
#define BSGI_MULTIVERSION 1
#define BSGI_TARGET_V4 __attribute__((target("arch=x86-64-v4")))
#define BSGI_TARGET_V3 __attribute__((target("arch=x86-64-v3")))
#else
#define BSGI_MULTIVERSION 0
#define BSGI_TARGET_V4
#define BSGI_TARGET_V3
#endif

template <typename K>
struct Entry {
    int dims, order, channels;
    bool float32, directions, uniform;
    K v4, v3, base;
};

#define BSGI_NAME(L, D, P, C, T, DIRS, U) kernel_##L##_##D##_##P##_##C##_##T##_##DIRS##_##U
#define BSGI_KERNEL(D, P, C, T, DIRS, U)                                                                  \
    BSGI_TARGET_V4 void BSGI_NAME(v4, D, P, C, T, DIRS, U)(const KernelArgs& a, size_t b, size_t e, double* o) { \
        evaluate_points<D, P, C, T, DIRS, U, 16>(a, b, e, o);                                                \
    }                                                                                                        \
    BSGI_TARGET_V3 void BSGI_NAME(v3, D, P, C, T, DIRS, U)(const KernelArgs& a, size_t b, size_t e, double* o) { \
        evaluate_points<D, P, C, T, DIRS, U, 8>(a, b, e, o);                                                 \
    }                                                                                                        \
    void BSGI_NAME(base, D, P, C, T, DIRS, U)(const KernelArgs& a, size_t b, size_t e, double* o) {         \
        evaluate_points<D, P, C, T, DIRS, U, 4>(a, b, e, o);                                                 \
    }
#define BSGI_ENTRY(D, P, C, T, DIRS, U)                                                                    \
    {D, P, C, sizeof(T) == 4, DIRS, U, &BSGI_NAME(v4, D, P, C, T, DIRS, U), &BSGI_NAME(v3, D, P, C, T, DIRS, U), \
     &BSGI_NAME(base, D, P, C, T, DIRS, U)},
// One point (parameter input only).
#define BSGI_POINT_NAME(L, D, P, C, T, U) point_##L##_##D##_##P##_##C##_##T##_##U
#define BSGI_POINT_KERNEL(D, P, C, T, DIRS, U)                                                                      \
    BSGI_TARGET_V4 void BSGI_POINT_NAME(v4, D, P, C, T, U)(const SplineLanes& l, const void* c, const double* x,    \
                                                            double* o) {                                             \
        evaluate_point<D, P, C, T, U, 16>(l, c, x, o);                                                             \
    }                                                                                                               \
    BSGI_TARGET_V3 void BSGI_POINT_NAME(v3, D, P, C, T, U)(const SplineLanes& l, const void* c, const double* x,    \
                                                            double* o) {                                             \
        evaluate_point<D, P, C, T, U, 8>(l, c, x, o);                                                              \
    }                                                                                                               \
    void BSGI_POINT_NAME(base, D, P, C, T, U)(const SplineLanes& l, const void* c, const double* x, double* o) {    \
        evaluate_point<D, P, C, T, U, 4>(l, c, x, o);                                                              \
    }
#define BSGI_POINT_ENTRY(D, P, C, T, DIRS, U)                                                                     \
    {D, P, C, sizeof(T) == 4, false, U, &BSGI_POINT_NAME(v4, D, P, C, T, U), &BSGI_POINT_NAME(v3, D, P, C, T, U), \
     &BSGI_POINT_NAME(base, D, P, C, T, U)},

// The shapes with kernels: 2D and 4D, degrees 0..3, 1 or 3 channels, both storages, uniform or
// not, and for 4D also the (u, v, direction) input of radiance.
#define BSGI_FOR_TU(X, D, P, C, DIRS) \
    X(D, P, C, double, DIRS, true) X(D, P, C, double, DIRS, false) X(D, P, C, float, DIRS, true) X(D, P, C, float, DIRS, false)
#define BSGI_FOR_C(X, D, P, DIRS) BSGI_FOR_TU(X, D, P, 1, DIRS) BSGI_FOR_TU(X, D, P, 3, DIRS)
#define BSGI_FOR_P(X, D, DIRS) BSGI_FOR_C(X, D, 1, DIRS) BSGI_FOR_C(X, D, 2, DIRS) BSGI_FOR_C(X, D, 3, DIRS) BSGI_FOR_C(X, D, 4, DIRS)
#define BSGI_FOR_ALL(X) BSGI_FOR_P(X, 2, false) BSGI_FOR_P(X, 4, false) BSGI_FOR_P(X, 4, true)
#define BSGI_FOR_PARAMS(X) BSGI_FOR_P(X, 2, false) BSGI_FOR_P(X, 4, false)

BSGI_FOR_ALL(BSGI_KERNEL)
BSGI_FOR_PARAMS(BSGI_POINT_KERNEL)

const Entry<Kernel> kKernels[] = {BSGI_FOR_ALL(BSGI_ENTRY)};
const Entry<PointKernel> kPointKernels[] = {BSGI_FOR_PARAMS(BSGI_POINT_ENTRY)};

// 2: x86-64-v4, 1: x86-64-v3, 0: baseline. BSGI_ISA in the environment may lower it (tests and
// benchmarks of the other versions).
int isa_level() {
    static const int level = [] {
        int l = 0;
#if BSGI_MULTIVERSION
        __builtin_cpu_init();
        const bool v3 = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") && __builtin_cpu_supports("bmi2");
        const bool v4 = v3 && __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
                        __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512dq");
        l = v4 ? 2 : (v3 ? 1 : 0);
#endif
        if (const char* env = std::getenv("BSGI_ISA")) {
            const std::string want = env;
            const int cap = want == "baseline" ? 0 : (want == "x86-64-v3" ? 1 : 2);
            l = std::min(l, cap);
        }
        return l;
    }();
    return level;
}

// Independent 256-bit multiply-adds, enough chains to cover their latency: the FMA pipes' peak.
BSGI_CLONES double fma_loop(long n) {
    v4d a[12];
    for (int i = 0; i < 12; ++i) a[i] = v4d{1.0 + i, 1, 1, 1};
    const v4d m = {0.999999, 0.999999, 0.999999, 0.999999}, c = {1e-7, 1e-7, 1e-7, 1e-7};
    for (long k = 0; k < n; ++k) {
        BSGI_UNROLL
        for (int i = 0; i < 12; ++i) a[i] = a[i] * m + c;
    }
    double s = 0;
    for (int i = 0; i < 12; ++i) s += a[i][0];
    return s;
}

}  // namespace

BSGI_CLONES void map_to_params(const HemisphereMap& hemisphere, const double* uv, const double* dirs, size_t n,
                               double* params) {
    const HemisphereMap map = hemisphere;
    double alpha[kMapBlock], beta[kMapBlock];
    for (size_t first = 0; first < n; first += kMapBlock) {
        const size_t m = std::min(n - first, kMapBlock);
        map_block(map, dirs + 3 * first, m, alpha, beta);
        double* x = params + 4 * first;
        const double* t = uv + 2 * first;
        for (size_t i = 0; i < m; ++i) x[4 * i] = t[2 * i], x[4 * i + 1] = t[2 * i + 1], x[4 * i + 2] = alpha[i], x[4 * i + 3] = beta[i];
    }
}

// Timed in this thread's CPU time: on a shared machine wall time would also count the time the
// thread waits for a core.
double measure_fma_rate() {
    const long n = 20'000'000;
    volatile double sink = 0;
    double best = 1e300;
    auto cpu_seconds = [] {
        timespec t;
        clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
        return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
    };
    for (int r = 0; r < 3; ++r) {
        const double t0 = cpu_seconds();
        sink = sink + fma_loop(n);
        best = std::min(best, cpu_seconds() - t0);
    }
    return 12.0 * n / best;
}

namespace {

template <typename K, size_t N>
K find_in(const Entry<K> (&table)[N], int dims, int order, int channels, bool float32, bool directions, bool uniform) {
    for (const Entry<K>& e : table)
        if (e.dims == dims && e.order == order && e.channels == channels && e.float32 == float32 &&
            e.directions == directions && e.uniform == uniform)
            return isa_level() == 2 ? e.v4 : (isa_level() == 1 ? e.v3 : e.base);
    return nullptr;
}

}  // namespace

Kernel find_kernel(int dims, int order, int channels, bool float32, bool directions, bool uniform) {
    return find_in(kKernels, dims, order, channels, float32, directions, uniform);
}

PointKernel find_point_kernel(int dims, int order, int channels, bool float32, bool uniform) {
    return find_in(kPointKernels, dims, order, channels, float32, false, uniform);
}

const char* kernel_isa() {
    static const char* names[] = {"baseline", "x86-64-v3", "x86-64-v4"};
    return names[isa_level()];
}

}  // namespace bsgi::detail
