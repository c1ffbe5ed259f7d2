#include "bsgi/memory_budget.h"

#include <atomic>
#include <cstdint>
#include <iomanip>
#include <sstream>

namespace bsgi {

namespace {
std::atomic<size_t> g_budget{size_t(2) << 30};
}

size_t memory_budget() { return g_budget.load(std::memory_order_relaxed); }
void set_memory_budget(size_t bytes) { g_budget.store(bytes, std::memory_order_relaxed); }

size_t array_bytes(const std::vector<size_t>& extents, size_t element_bytes) {
    size_t n = element_bytes;
    for (size_t e : extents)
        if (__builtin_mul_overflow(n, e, &n)) return SIZE_MAX;
    return n;
}

std::string format_bytes(size_t bytes) {
    static const char* units[] = {"bytes", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"};
    double v = double(bytes);
    int u = 0;
    while (v >= 1024 && u < 6) v /= 1024, ++u;
    std::ostringstream s;
    if (u == 0) s << bytes << " bytes";
    else s << std::setprecision(3) << v << ' ' << units[u];
    return s.str();
}

size_t check_memory_budget(const std::string& what, const std::vector<size_t>& extents, size_t element_bytes) {
    const size_t bytes = array_bytes(extents, element_bytes);
    const size_t budget = memory_budget();
    if (bytes > budget) {
        std::ostringstream msg;
        msg << what << ": ";
        for (size_t i = 0; i < extents.size(); ++i) msg << (i ? " x " : "") << extents[i];
        msg << " x " << element_bytes << " bytes = "
            << (bytes == SIZE_MAX ? std::string("more than 16 EiB") : format_bytes(bytes))
            << " exceeds the memory budget of " << format_bytes(budget) << " (bsgi.set_memory_budget raises it)";
        throw MemoryBudgetExceeded(msg.str());
    }
    return bytes;
}

}  // namespace bsgi
