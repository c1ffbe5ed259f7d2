// parallel_for over an index range with std::thread (not OpenMP: Blender already loads a libgomp).
#pragma once
#include <algorithm>
#include <atomic>
#include <cstddef>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace bsgi {

inline int resolve_threads(int threads) {
    if (threads > 0) return threads;
    const unsigned hw = std::thread::hardware_concurrency();
    return hw == 0 ? 1 : static_cast<int>(hw);
}

// Calls body(begin, end) on chunks of [0, count) from `threads` threads. Chunks are handed out
// dynamically so uneven work balances. Stops handing out chunks once `stop` is set. The first
// exception thrown by body is rethrown on the calling thread.
template <typename Body>
void parallel_for(size_t count, size_t chunk, int threads, Body&& body,
                  const std::atomic<bool>* stop = nullptr) {
    threads = std::min<int>(resolve_threads(threads), static_cast<int>((count + chunk - 1) / std::max<size_t>(chunk, 1)));
    chunk = std::max<size_t>(chunk, 1);
    std::atomic<size_t> next{0};
    std::exception_ptr error;
    std::mutex error_mutex;
    std::atomic<bool> failed{false};
    auto worker = [&]() {
        for (;;) {
            if (failed.load(std::memory_order_relaxed)) return;
            if (stop && stop->load(std::memory_order_relaxed)) return;
            const size_t begin = next.fetch_add(chunk);
            if (begin >= count) return;
            try {
                body(begin, std::min(count, begin + chunk));
            } catch (...) {
                std::lock_guard<std::mutex> lock(error_mutex);
                if (!error) error = std::current_exception();
                failed = true;
            }
        }
    };
    if (threads <= 1) {
        worker();
    } else {
        std::vector<std::thread> pool;
        pool.reserve(threads - 1);
        for (int i = 1; i < threads; ++i) pool.emplace_back(worker);
        worker();
        for (auto& t : pool) t.join();
    }
    if (error) std::rethrow_exception(error);
}

}  // namespace bsgi
