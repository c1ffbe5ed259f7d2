// Memory guard: sizes are computed before allocating, and requests over a budget are refused.
#pragma once
#include <cstddef>
#include <stdexcept>
#include <string>
#include <vector>

namespace bsgi {

// Thrown instead of allocating more than the budget; the message names the sizes.
class MemoryBudgetExceeded : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// Process-wide budget for one allocation of spline data, in bytes (default 2 GiB). Thread-safe.
size_t memory_budget();
void set_memory_budget(size_t bytes);

// Bytes of an array of extents[0] x ... x extents[k-1] elements of element_bytes each, with
// overflow detected (returns SIZE_MAX then).
size_t array_bytes(const std::vector<size_t>& extents, size_t element_bytes);

// Throws MemoryBudgetExceeded naming `what`, the extents and the element size when
// array_bytes(extents, element_bytes) is over the budget. Returns the byte count.
size_t check_memory_budget(const std::string& what, const std::vector<size_t>& extents, size_t element_bytes);

// "1.5 MiB" style.
std::string format_bytes(size_t bytes);

}  // namespace bsgi
