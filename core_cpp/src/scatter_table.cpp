#include "bsgi/scatter_table.h"

#include <cmath>

#include "bsgi/cosine_rule.h"
#include "bsgi/gather.h"

namespace bsgi {

namespace {

constexpr double kPi = 3.14159265358979323846;

// Draw m of n in [0, 1)^3. The BSDF's direction comes from (u1, u2), a Fibonacci lattice
// ((m + 1/2) / n, the golden ratio's multiples): n distinct values along each coordinate, an
// even spread at every n. u0, a lobe's choice in a BSDF of several, is the column of m in n
// equal-area cells of the unit square (floor(sqrt(n)) rows, the first n mod rows one cell
// longer), so that each lobe's share of the draws is its probability's, row by row, and every
// row covers a span of u1. Deterministic, so the solve has no noise. (Until 7 December a lobe's
// direction came from (the cells' row, the golden ratio): 4 distinct values of u1 at 16 draws;
// GGX floors under a white world were 0.99% from their many-draw value over 9-64 draws, the
// lattice 0.37%; before that, a sqrt(n) x sqrt(n) grid at every n left cells out or in twice
// at 20 or 32 draws.)
void lattice_draw(int m, int n, double* u) {
    int rows = std::max(1, int(std::sqrt(double(n))));
    while (rows * rows > n) --rows;
    while ((rows + 1) * (rows + 1) <= n) ++rows;
    const int cells = n / rows, longer = n % rows;  // rows [0, longer) have cells + 1
    const bool long_row = m < longer * (cells + 1);
    const int in_row = long_row ? cells + 1 : cells;
    const int column = long_row ? m % in_row : (m - longer * (cells + 1)) % cells;
    u[0] = (column + 0.5) / in_row;
    u[1] = (m + 0.5) / n;
    u[2] = std::fmod((m + 0.5) * 0.6180339887498949, 1.0);
}

}  // namespace

ScatterTable::ScatterTable(const Receiver& r, int first, int last, bool mirror, int nt, int np, int nb)
    : bsdf_(r.bsdf), first_(first), last_(last), nt_(nt), np_(np), nb_(nb),
      per_node_(r.per_node), mirror_(mirror) {
    in_sides_ = r.bsdf->transmits() ? 2 : 1;
    for (int side = first; side < last; ++side)
        for (size_t a = 0; a < r.per_node; ++a) outgoing_.push_back(r.outgoing(mirror ? 0 : side, a));
    // The cosine nodes as one strategy over the sides sampled: n_cos nodes on each side, so
    // in_sides * n_cos samples of density |cos| / (pi * in_sides). The rule's nodes are not
    // equally weighted (CosineRule): each node's term takes its weight, the balance heuristic
    // keeps this smooth density (its weights sum to 1 wherever it is evaluated, so the
    // combination stays unbiased; with the nodes' own, piecewise density it was 0.1% low).
    n_strategy_ = in_sides_ * (double(nt) * np);
    const CosineRule& rule = cosine_rule(nt, np);
    for (int side_in = 0; side_in < in_sides_; ++side_in)
        for (int m = 0; m < rule.size(); ++m) {
            Vec3 wi = rule.direction(m);
            if (side_in) wi.z = -wi.z;
            incoming_.push_back(wi);
            node_weight_.push_back(rule.weight(m));
        }
    const size_t row = outgoing_.size();
    const bool keep = kept(row, incoming_.size());
    terms_.resize(keep ? incoming_.size() * row : row);
    if (keep) filled_.assign(incoming_.size(), 0);
    branches_ = r.bsdf->gather_branches();
    const size_t per_value = size_t(nb) * branches_;
    samples_.resize(row * per_value);
    for (size_t v = 0; v < row; ++v) {
        const Vec3& wo = outgoing_[v];
        for (int m = 0; m < nb; ++m) {
            double u[3];
            lattice_draw(m, nb, u);
            BsdfSample drawn[Bsdf::kGatherBranches];
            r.bsdf->sample_branches(wo, u[0], u[1], u[2], drawn);
            for (int k = 0; k < branches_; ++k) {
                const BsdfSample& s = drawn[k];
                if (!(s.pdf > 0)) continue;
                Sample& out = samples_[v * per_value + size_t(m) * branches_ + k];
                out.wi = s.wi;
                if (s.delta) {
                    out.kind = Sample::Kind::Delta;
                    out.f = s.weight;
                    continue;
                }
                // Each branch's region gets nb draws of its own density.
                double pb;
                out.kind = Sample::Kind::Smooth;
                out.f = r.bsdf->eval_gather_pdf(wo, s.wi, pb);
                out.scale = std::abs(s.wi.z) / (n_strategy_ * cosine_pdf(s.wi) + nb * pb);
            }
        }
    }
}

double ScatterTable::cosine_pdf(const Vec3& w) const {
    return (w.z < 0 && in_sides_ == 1) ? 0.0 : std::abs(w.z) / kPi / in_sides_;
}

size_t ScatterTable::bytes(size_t values, size_t incoming, int nb, int branches) {
    return (kept(values, incoming) ? incoming : 1) * values * sizeof(Term) + values * size_t(nb) * branches * sizeof(Sample) +
           incoming * (sizeof(Vec3) + sizeof(double) + 1) + values * sizeof(Vec3);
}

bool ScatterTable::matches(const Receiver& r, int first, int last, bool mirror, int nt, int np, int nb) const {
    if (r.bsdf != bsdf_ || first != first_ || last != last_ || mirror != mirror_ || nt != nt_ ||
        np != np_ || nb != nb_ || r.per_node != per_node_)
        return false;
    size_t v = 0;
    for (int side = first; side < last; ++side)
        for (size_t a = 0; a < r.per_node; ++a, ++v) {
            const Vec3 wo = r.outgoing(mirror ? 0 : side, a);
            if (!(wo.x == outgoing_[v].x && wo.y == outgoing_[v].y && wo.z == outgoing_[v].z)) return false;
        }
    return true;
}

const ScatterTable::Term* ScatterTable::terms(size_t t) {
    const size_t row = outgoing_.size();
    if (filled_.empty()) {
        fill(t, terms_.data());
        return terms_.data();
    }
    Term* out = terms_.data() + t * row;
    if (!filled_[t]) fill(t, out), filled_[t] = 1;
    return out;
}

void ScatterTable::fill(size_t t, Term* row) const {
    const Vec3& wi = incoming_[t];
    const double pc = n_strategy_ * cosine_pdf(wi);
    for (size_t v = 0; v < outgoing_.size(); ++v) {
        double pb;
        Term& term = row[v];
        term.f = bsdf_->eval_gather_pdf(outgoing_[v], wi, pb);
        // (weight |cos| / pdf > 0 at every cosine node: 0 marks a term without light; a layered
        // coat's glossy part is negative where it takes more from the base than it reflects.)
        term.scale = !is_zero(term.f) ? node_weight_[t] * std::abs(wi.z) / (pc + nb_ * pb) : 0;
    }
}

}  // namespace bsgi
