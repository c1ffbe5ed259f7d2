// Progress of a long computation, readable and cancellable from any thread without locks on the
// hot path: the solver advances it, a UI polls it.
#pragma once
#include <algorithm>
#include <atomic>
#include <mutex>
#include <stdexcept>
#include <string>

namespace bsgi {

struct Cancelled : std::runtime_error {
    Cancelled() : std::runtime_error("solve cancelled") {}
};

class Progress {
public:
    // Stage `index` of `count` equal parts of the whole, with `total` units of work.
    void begin_stage(const std::string& name, int index, int count, size_t total) {
        {
            std::lock_guard<std::mutex> lock(mutex_);
            stage_ = name;
        }
        stage_index_ = index;
        stage_count_ = count;
        total_ = total == 0 ? 1 : total;
        done_ = 0;
    }
    // Names the whole solve the stages that follow belong to (a pass of refinement, which solves
    // again from the start): stage() reads "label: stage" until an empty label.
    void begin_pass(const std::string& label) {
        std::lock_guard<std::mutex> lock(mutex_);
        pass_ = label;
    }
    void advance(size_t units) { done_.fetch_add(units, std::memory_order_relaxed); }
    double fraction() const {
        const double within = double(done_.load(std::memory_order_relaxed)) / double(total_.load());
        return std::min(1.0, (stage_index_.load() + std::min(within, 1.0)) / std::max(1, stage_count_.load()));
    }
    std::string stage() const {
        std::lock_guard<std::mutex> lock(mutex_);
        return pass_.empty() ? stage_ : pass_ + ": " + stage_;
    }
    void cancel() { cancelled_ = true; }
    bool cancelled() const { return cancelled_.load(std::memory_order_relaxed); }
    const std::atomic<bool>* cancel_flag() const { return &cancelled_; }
    void throw_if_cancelled() const {
        if (cancelled()) throw Cancelled();
    }
    void finish() {
        stage_index_ = stage_count_.load();
        std::lock_guard<std::mutex> lock(mutex_);
        stage_ = "done";
    }

private:
    mutable std::mutex mutex_;
    std::string stage_ = "waiting", pass_;
    std::atomic<int> stage_index_{0}, stage_count_{1};
    std::atomic<size_t> total_{1}, done_{0};
    std::atomic<bool> cancelled_{false};
};

}  // namespace bsgi
