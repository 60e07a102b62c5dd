#include "raindrop/render/scratch_pool.h"

#include <algorithm>
#include <mutex>
#include <new>
#include <unordered_map>
#include <vector>

namespace raindrop {
namespace {

constexpr std::size_t kAlignment = 64;

class Pool {
 public:
  std::byte* take(std::size_t bytes) {
    std::lock_guard<std::mutex> lock(mutex_);
    auto best = free_.end();
    for (auto it = free_.begin(); it != free_.end(); ++it)
      if (capacity_[*it] >= bytes && (best == free_.end() || capacity_[*it] < capacity_[*best])) best = it;
    if (best != free_.end()) {
      std::byte* data = *best;
      free_.erase(best);
      return data;
    }
    const std::size_t capacity = std::max<std::size_t>(bytes, 1);
    auto* data = static_cast<std::byte*>(::operator new(capacity, std::align_val_t(kAlignment)));
    capacity_[data] = capacity;
    return data;
  }

  void give(std::byte* data) {
    std::lock_guard<std::mutex> lock(mutex_);
    free_.push_back(data);
    if (static_cast<int>(free_.size()) > kScratchBuffersKept) {
      // Full: the smallest goes (the large ones are the ones worth keeping).
      auto smallest = std::min_element(free_.begin(), free_.end(),
                                       [&](std::byte* a, std::byte* b) { return capacity_[a] < capacity_[b]; });
      std::byte* drop = *smallest;
      free_.erase(smallest);
      capacity_.erase(drop);
      ::operator delete(drop, std::align_val_t(kAlignment));
    }
  }

  int free_count() {
    std::lock_guard<std::mutex> lock(mutex_);
    return static_cast<int>(free_.size());
  }

 private:
  std::mutex mutex_;
  std::vector<std::byte*> free_;
  std::unordered_map<std::byte*, std::size_t> capacity_;  // every buffer the pool made, free or not
};

// Never destroyed: buffers may come back from static objects during exit.
Pool& pool() {
  static Pool* p = new Pool;
  return *p;
}

// OpenCV's standard allocator, with the data from the pool (as its StdMatAllocator lays a
// matrix out: continuous rows, steps from the element size).
class ScratchMatAllocator : public cv::MatAllocator {
 public:
  cv::UMatData* allocate(int dims, const int* sizes, int type, void* data0, size_t* step, cv::AccessFlag,
                         cv::UMatUsageFlags) const override {
    size_t total = CV_ELEM_SIZE(type);
    for (int i = dims - 1; i >= 0; --i) {
      if (step) {
        if (data0 && step[i] != cv::Mat::AUTO_STEP) {
          CV_Assert(total <= step[i]);
          total = step[i];
        } else {
          step[i] = total;
        }
      }
      total *= sizes[i];
    }
    auto* u = new cv::UMatData(this);
    if (data0) {
      u->data = u->origdata = static_cast<uchar*>(data0);
      u->flags |= cv::UMatData::USER_ALLOCATED;
    } else {
      u->data = u->origdata = reinterpret_cast<uchar*>(pool().take(total));
    }
    u->size = total;
    return u;
  }

  bool allocate(cv::UMatData* u, cv::AccessFlag, cv::UMatUsageFlags) const override { return u != nullptr; }

  void deallocate(cv::UMatData* u) const override {
    if (!u) return;
    CV_Assert(u->urefcount == 0 && u->refcount == 0);
    if (!(u->flags & cv::UMatData::USER_ALLOCATED)) pool().give(reinterpret_cast<std::byte*>(u->origdata));
    delete u;
  }
};

}  // namespace

void ScratchRelease::operator()(std::byte* data) const {
  if (data) pool().give(data);
}

ScratchBytes scratch_bytes(std::size_t bytes) {
  return ScratchBytes(pool().take(bytes));
}

cv::Mat scratch_mat(int rows, int cols, int type) {
  static ScratchMatAllocator* allocator = new ScratchMatAllocator;  // outlives every matrix
  cv::Mat m;
  m.allocator = allocator;
  m.create(rows, cols, type);
  return m;
}

int scratch_buffers_free() { return pool().free_count(); }

}  // namespace raindrop
