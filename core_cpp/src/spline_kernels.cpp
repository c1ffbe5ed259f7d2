// The hot path of spline evaluation: one kernel per (dimensions, order, channels, storage, input),
// so that every loop has a compile-time trip count and the innermost contraction is a short
// fixed-length multiply-add over contiguous coefficients.
//
// Per point: for each axis the span and the d+1 non-zero basis values (Horner on the per-span
// power form, no division); then (17)/(18) reassociated so that the first D-1 axes give
// P^(D-1) weights (products of their basis values) and the last axis, whose P coefficients of
// C channels are contiguous, is a row of P*C values: acc += weight * row over the P^(D-1) rows,
// and finally out_c = sum_l B_l acc[l][c]. For the 4D quadratic RGB radiance spline that is 27
// rows of 9 values: 243 multiply-adds, the least of any contraction order.
#include "spline_kernels.h"

#include <algorithm>
#include <cfloat>
#include <cmath>

namespace bsgi::detail {

namespace {

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
// The wheel keeps the x86-64 baseline; the loader picks the best clone for the running CPU.
#define BSGI_CLONES __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#define BSGI_CLONES
#endif
#define BSGI_INLINE inline __attribute__((always_inline))
// Loops with compile-time trip counts are unrolled completely, so small arrays live in registers.
#define BSGI_UNROLL _Pragma("GCC unroll 64")

constexpr int ipow(int b, int e) { return e == 0 ? 1 : b * ipow(b, e - 1); }

// Span I and local parameter s = (x - t_I) / (t_{I+1} - t_I) of x (already in the domain).
// Uniform spans: one multiplication, no knot is read; on a knot x may land at s = 1 of the span
// on its left instead of s = 0 of the one on its right, the same value up to rounding since the
// spline is continuous there (uniform spans have no repeated inner knots).
template <int P, bool Uniform>
BSGI_INLINE int find_span(const AxisData& ax, double x, double& s) {
    constexpr int d = P - 1;
    if constexpr (Uniform) {
        const double u = (x - ax.lo) * ax.inv_h;
        int j = static_cast<int>(u);
        j = std::min(j, ax.last_span - d);
        s = u - j;
        return d + j;
    } else {
        // Binary search for the last knot <= x among t_d .. t_last.
        const double* t = ax.knots;
        int lo = d, hi = ax.last_span;
        while (lo < hi) {
            const int mid = (lo + hi + 1) >> 1;
            if (t[mid] <= x) lo = mid;
            else hi = mid - 1;
        }
        s = (x - t[lo]) * ax.inv_width[lo - d];
        return lo;
    }
}

template <int D, bool Dirs>
BSGI_INLINE void load(const KernelArgs& a, size_t i, double* x) {
    if constexpr (Dirs) {
        x[0] = a.uv[2 * i], x[1] = a.uv[2 * i + 1];
        a.map->to_disc(a.dirs[3 * i], a.dirs[3 * i + 1], a.dirs[3 * i + 2], x + 2);
    } else {
        for (int k = 0; k < D; ++k) x[k] = a.params[i * D + k];
    }
}

// 32-byte vectors (GCC/Clang vector extension): AVX registers in the x86-64-v3 and v4 clones,
// pairs of SSE2 registers in the baseline one.
typedef double v4d __attribute__((vector_size(32)));
typedef float v16f __attribute__((vector_size(64)));

// Contraction arithmetic in the storage type. Double (float64 coefficients): 4 lanes, and a row
// whose length is not a multiple of 4 ends with a load moved back to end at the row's end
// (overlapping the one before), so nothing past the coefficients is read. Float (float32
// coefficients): 16 lanes, one AVX-512 register (two AVX2 ones, four SSE ones) for a whole
// row of up to 16 values; the row may be read past its end, which the storage allows
// (TensorSpline pads float32 coefficients with kFloat32Padding zeros). See the bound in
// tensor_spline.h for float arithmetic.
template <typename T>
struct Lanes;
template <>
struct Lanes<double> {
    using V = v4d;
    static constexpr int W = 4;
    static constexpr bool padded = false;
};
template <>
struct Lanes<float> {
    using V = v16f;
    static constexpr int W = 16;
    static constexpr bool padded = true;
};

template <typename V, typename T>
BSGI_INLINE V load_vec(const T* p) {
    V v;
    __builtin_memcpy(&v, p, sizeof v);
    return v;
}

// Basis values (lanes 0..P-1) of one parameter on one axis; returns the offset of the first
// non-zero coefficient along the axis, in values.
template <int P, bool Uniform>
BSGI_INLINE size_t axis_basis(const AxisData& ax, double x, v4d& b, bool& finite) {
    const bool ok = std::fabs(x) <= DBL_MAX;  // false for NaN and infinities
    finite &= ok;
    x = ok ? x : ax.lo;
    x = std::min(std::max(x, ax.lo), ax.hi);  // clamp to the domain
    double s;
    const int span = find_span<P, Uniform>(ax, x, s);
    // Horner on the power form: rows of the table are P apart, lanes >= P unused (the table is
    // padded so that the last load stays inside it).
    const double* c = ax.poly + size_t(span - (P - 1)) * P * P;
    b = load_vec<v4d>(c + (P - 1) * P);
    BSGI_UNROLL
    for (int e = P - 2; e >= 0; --e) b = b * s + load_vec<v4d>(c + e * P);
    return size_t(span - (P - 1)) * ax.stride;
}

// What the contraction of one point needs: its basis values and first coefficient.
template <int D, typename T>
struct Prepared {
    v4d b[D];  // basis values of each axis in lanes 0..P-1
    const T* block;
    bool finite;
};

typedef float v4f __attribute__((vector_size(16)));
typedef int v4si __attribute__((vector_size(16)));

// The axes of a uniform-span kernel as lanes of one vector (D <= 4): span and local parameter
// of all parameters of a point in a few vector instructions.
struct UniformLanes {
    v4d lo, hi, inv_h;
    v4si last;  // last span index - degree
    const double* poly[4];
    size_t stride[4];
};

template <int D>
UniformLanes uniform_lanes(const AxisData* ax) {
    UniformLanes u{};
    for (int k = 0; k < D; ++k) {
        u.lo[k] = ax[k].lo, u.hi[k] = ax[k].hi, u.inv_h[k] = ax[k].inv_h;
        u.last[k] = ax[k].last_span - ax[k].degree;
        u.poly[k] = ax[k].poly, u.stride[k] = ax[k].stride;
    }
    return u;
}

template <int D, int P, typename T, bool Dirs>
BSGI_INLINE Prepared<D, T> prepare_uniform(const KernelArgs& args, const UniformLanes& u, const T* coeffs, size_t i) {
    static_assert(D <= 4, "one lane per axis");
    Prepared<D, T> p;
    // The parameters as one vector, built in registers (a round trip through memory would stall
    // store forwarding).
    v4d x;
    if constexpr (Dirs) {
        double ab[2];
        args.map->to_disc(args.dirs[3 * i], args.dirs[3 * i + 1], args.dirs[3 * i + 2], ab);
        x = v4d{args.uv[2 * i], args.uv[2 * i + 1], ab[0], ab[1]};
    } else if constexpr (D == 4) {
        x = load_vec<v4d>(args.params + 4 * i);
    } else {
        x = v4d{0, 0, 0, 0};
        BSGI_UNROLL
        for (int k = 0; k < D; ++k) x[k] = args.params[D * i + k];
    }
    const auto ok = (x < 0 ? -x : x) <= DBL_MAX;  // false for NaN and infinities
    p.finite = (ok[0] & ok[1] & ok[2] & ok[3]) != 0;
    x = ok ? x : u.lo;
    x = x < u.lo ? u.lo : x;  // clamp to the domain
    x = x > u.hi ? u.hi : x;
    const v4d t = (x - u.lo) * u.inv_h;
    v4si j = __builtin_convertvector(t, v4si);
    j = j > u.last ? u.last : j;
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

template <int D, int P, typename T, bool Dirs, bool Uniform>
BSGI_INLINE Prepared<D, T> prepare(const KernelArgs& args, const AxisData* ax, const T* coeffs, size_t i) {
    Prepared<D, T> p;
    double x[D];
    load<D, Dirs>(args, i, x);
    p.finite = true;
    p.block = coeffs;
    BSGI_UNROLL
    for (int k = 0; k < D; ++k) p.block += axis_basis<P, Uniform>(ax[k], x[k], p.b[k], p.finite);
    return p;
}

template <int D, int P, int C, typename T>
BSGI_INLINE void contract(const Prepared<D, T>& p, const AxisData* ax, double* o) {
    constexpr int G = ipow(P, D - 2);  // groups of rows: all index combinations of axes 0 .. D-3
    constexpr int L = P * C;           // values per row (last axis x channels, contiguous)
    using V = typename Lanes<T>::V;
    constexpr int W = Lanes<T>::W;
    // A row is covered by NV loads of W values (see Lanes); unpadded rows shorter than W are
    // done in scalars.
    constexpr bool padded = Lanes<T>::padded;
    constexpr int NV = L < W && !padded ? 0 : (L + W - 1) / W;
    const size_t row_stride = ax[D - 2].stride;
    // Groups: index g of axes 0 .. D-3 (last fastest); its weight is the product of their basis
    // values and its rows start at the sum of index * stride.
    T w[G];
    const T* group[G];
    BSGI_UNROLL
    for (int g = 0; g < G; ++g) {
        double wg = 1.0;
        const T* q = p.block;
        int r = g;
        BSGI_UNROLL
        for (int k = D - 3; k >= 0; --k) wg *= p.b[k][r % P], q += (r % P) * ax[k].stride, r /= P;
        if constexpr (D != 4) w[g] = T(wg);
        group[g] = q;
    }
    if constexpr (D == 4) {  // the P x P products as P vector products, converted in one go
        BSGI_UNROLL
        for (int i = 0; i < P; ++i) {
            const v4d wi = p.b[0][i] * p.b[1];
            if constexpr (sizeof(T) == 4) {
                const v4f f = __builtin_convertvector(wi, v4f);
                BSGI_UNROLL
                for (int j = 0; j < P; ++j) w[i * P + j] = f[j];
            } else {
                BSGI_UNROLL
                for (int j = 0; j < P; ++j) w[i * P + j] = wi[j];
            }
        }
    }
    // (18): in each group the P rows of axis D-2 go to P separate sums (independent chains)
    // weighted by the group weight only; the basis values of axis D-2 are applied once at the
    // end, then those of the last axis (within the row) per channel.
    T row[NV * W > L ? NV * W : L];
    if constexpr (NV > 0) {
        V acc[P][NV] = {};
        BSGI_UNROLL
        for (int g = 0; g < G; ++g)
            BSGI_UNROLL
            for (int r = 0; r < P; ++r)
                BSGI_UNROLL
                for (int v = 0; v < NV; ++v)
                    acc[r][v] += w[g] * load_vec<V>(group[g] + r * row_stride + (v + 1 < NV || padded ? W * v : L - W));
        BSGI_UNROLL
        for (int v = 0; v < NV; ++v) {
            V sum = T(p.b[D - 2][0]) * acc[0][v];
            BSGI_UNROLL
            for (int r = 1; r < P; ++r) sum += T(p.b[D - 2][r]) * acc[r][v];
            BSGI_UNROLL
            for (int e = 0; e < W; ++e) row[(v + 1 < NV || padded ? W * v : L - W) + e] = sum[e];
        }
    } else {
        BSGI_UNROLL
        for (int e = 0; e < L; ++e) row[e] = 0;
        BSGI_UNROLL
        for (int g = 0; g < G; ++g)
            BSGI_UNROLL
            for (int r = 0; r < P; ++r) {
                const T wr = w[g] * T(p.b[D - 2][r]);
                BSGI_UNROLL
                for (int e = 0; e < L; ++e) row[e] += wr * group[g][r * row_stride + e];
            }
    }
    BSGI_UNROLL
    for (int c = 0; c < C; ++c) {
        double v = 0;
        BSGI_UNROLL
        for (int l = 0; l < P; ++l) v += p.b[D - 1][l] * double(row[l * C + c]);
        o[c] = p.finite ? v : NAN;
    }
}

template <int D, int P, int C, typename T, bool Dirs, bool Uniform>
BSGI_INLINE void evaluate_points(const KernelArgs& args, size_t begin, size_t end, double* out) {
    static_assert(D >= 2, "the last two axes are the rows and their accumulators");
    static_assert(P <= 4, "one vector of basis values per axis");
    if (begin >= end) return;
    // Local copies: the compiler then knows the output stores cannot change them.
    AxisData ax[D];
    for (int k = 0; k < D; ++k) ax[k] = args.axes[k];
    const T* const coeffs = static_cast<const T*>(args.coeffs);
    // Software pipeline: the spans and basis of the next point are computed in the same
    // iteration as the contraction of this one, two independent dependency chains that the
    // out-of-order core overlaps.
    const UniformLanes lanes = uniform_lanes<D>(ax);
    auto prep = [&](size_t i) {
        if constexpr (Uniform) return prepare_uniform<D, P, T, Dirs>(args, lanes, coeffs, i);
        else return prepare<D, P, T, Dirs, false>(args, ax, coeffs, i);
    };
    // Two states used in turn rather than copied, so that nothing goes through memory.
    Prepared<D, T> a = prep(begin), b;
    for (size_t i = begin;;) {
        b = prep(i + 1 < end ? i + 1 : i);
        contract<D, P, C, T>(a, ax, out + i * C);
        if (++i == end) break;
        a = prep(i + 1 < end ? i + 1 : i);
        contract<D, P, C, T>(b, ax, out + i * C);
        if (++i == end) break;
    }
}

struct Entry {
    int dims, order, channels;
    bool float32, directions, uniform;
    Kernel kernel;
};

#define BSGI_KERNEL(D, P, C, T, DIRS, U)                                                                     \
    BSGI_CLONES void kernel_##D##_##P##_##C##_##T##_##DIRS##_##U(const KernelArgs& a, size_t b, size_t e,    \
                                                                 double* o) {                               \
        evaluate_points<D, P, C, T, DIRS, U>(a, b, e, o);                                                   \
    }
#define BSGI_ENTRY(D, P, C, T, DIRS, U) \
    {D, P, C, sizeof(T) == 4, DIRS, U, &kernel_##D##_##P##_##C##_##T##_##DIRS##_##U},

// The shapes with kernels: 2D and 4D, degrees 0..3, 1 or 3 channels, both storages, uniform or
// not, and for 4D also the (u, v, direction) input of radiance.
#define BSGI_FOR_TU(X, D, P, C, DIRS) \
    X(D, P, C, double, DIRS, true) X(D, P, C, double, DIRS, false) X(D, P, C, float, DIRS, true) X(D, P, C, float, DIRS, false)
#define BSGI_FOR_C(X, D, P, DIRS) BSGI_FOR_TU(X, D, P, 1, DIRS) BSGI_FOR_TU(X, D, P, 3, DIRS)
#define BSGI_FOR_P(X, D, DIRS) BSGI_FOR_C(X, D, 1, DIRS) BSGI_FOR_C(X, D, 2, DIRS) BSGI_FOR_C(X, D, 3, DIRS) BSGI_FOR_C(X, D, 4, DIRS)
#define BSGI_FOR_ALL(X) BSGI_FOR_P(X, 2, false) BSGI_FOR_P(X, 4, false) BSGI_FOR_P(X, 4, true)

BSGI_FOR_ALL(BSGI_KERNEL)

const Entry kKernels[] = {BSGI_FOR_ALL(BSGI_ENTRY)};

}  // namespace

Kernel find_kernel(int dims, int order, int channels, bool float32, bool directions, bool uniform) {
    for (const Entry& e : kKernels)
        if (e.dims == dims && e.order == order && e.channels == channels && e.float32 == float32 &&
            e.directions == directions && e.uniform == uniform)
            return e.kernel;
    return nullptr;
}

}  // namespace bsgi::detail
