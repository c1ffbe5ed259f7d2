#pragma once
// The BSDF's share of a view-dependent receiver's hemispherical gather (Gatherer::gather_sides):
// for every integration direction and outgoing angular node, f(wo, wi) and the multiple
// importance sampling weight; for every BSDF sample, its direction and weight. All of it lives
// in the receiver's local frame and so is the same at every spatial node: computed once per
// receiver, density and side, and read at each node, instead of evaluating the BSDF nodes x
// directions x angular nodes times (a third of a glossy scene's bounce time went there).
// The terms are the gather's own arithmetic, factor by factor: the gathered values are the same
// to the last bit as with the BSDF evaluated at every node.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "bsgi/vec3.h"

namespace bsgi {

struct Receiver;
class Bsdf;

class ScatterTable {
public:
    // A cosine node's term for one outgoing value: L * f * scale; scale 0 where f has no
    // positive part (the term is skipped).
    struct Term {
        Vec3 f;
        double scale = 0;
    };
    // A BSDF sample for one outgoing value: along wi, L * f / nb for a delta lobe (f is its
    // throughput), L * f * scale for a smooth one.
    struct Sample {
        enum class Kind : uint8_t { None, Delta, Smooth };
        Vec3 wi, f;
        double scale = 0;
        Kind kind = Kind::None;
    };

    // Sides [first, last) of r's values, mirrored for an opaque back side (Receiver::scatter),
    // with nt x np cosine nodes per incoming side and nb BSDF samples per outgoing value. Rows of
    // terms are kept while all of them take at most kKeptBytes; beyond, one row is recomputed
    // at each use (a refined gather of 16 times the nodes).
    ScatterTable(const Receiver& r, int first, int last, bool mirror, int nt, int np, int nb);
    // Whether this table is the one those arguments would build.
    bool matches(const Receiver& r, int first, int last, bool mirror, int nt, int np, int nb) const;
    // Bytes of the table for `values` outgoing values, `incoming` cosine nodes and nb draws of
    // `branches` samples each (Bsdf::gather_branches).
    static size_t bytes(size_t values, size_t incoming, int nb, int branches);

    // Cosine nodes over the incoming sides: incoming side slowest, then the rule's order.
    size_t incoming_count() const { return incoming_.size(); }
    const Vec3& incoming(size_t t) const { return incoming_[t]; }
    // The terms of node t, (last - first) * per_node of them, side-major.
    const Term* terms(size_t t);
    // (last - first) * per_node * samples_per_value() samples: side slowest, then value, then
    // draw, then branch.
    const std::vector<Sample>& samples() const { return samples_; }
    size_t samples_per_value() const { return size_t(nb_) * branches_; }

    static constexpr size_t kKeptBytes = size_t(32) << 20;
    // Tables a thread keeps (Gatherer::scatter_table).
    static constexpr size_t kRecent = 2;

private:
    static bool kept(size_t values, size_t incoming) { return incoming * values * sizeof(Term) <= kKeptBytes; }
    void fill(size_t t, Term* row) const;
    // The cosine nodes' density at w, as one strategy over the incoming sides.
    double cosine_pdf(const Vec3& w) const;

    const Bsdf* bsdf_;
    int first_, last_, nt_, np_, nb_;
    size_t per_node_;
    bool mirror_;
    std::vector<Vec3> outgoing_;  // the values' outgoing directions, as the BSDF sees them
    std::vector<Vec3> incoming_;
    std::vector<double> node_weight_;  // the cosine rule's weight of node t
    double n_strategy_;
    int in_sides_;
    int branches_ = 1;
    std::vector<Term> terms_;
    std::vector<uint8_t> filled_;  // per node, if the rows are kept
    std::vector<Sample> samples_;
};

}  // namespace bsgi
