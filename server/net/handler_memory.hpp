// Memory for one connection's asynchronous operations, reused from operation to operation.
// Asio keeps one freed operation per thread for reuse, but only one of at most 1,020 bytes;
// a Beast WebSocket write (its buffer sequence alone is 1 KiB) is larger, so each message
// written was two heap allocations. A handler wrapped by `with_memory` has its operations
// allocated from a few fixed blocks here instead (the heap when all are taken, or for a
// larger one).
//
// Lifetime: Asio may give an operation's memory back after its handler was destroyed (an
// io_context shutting down with the operation pending), and a handler may allocate again
// after its connection is gone (a timer's handler, cancelled by the connection's
// destruction, is moved out of its operation, the operation's block given back, and the
// handler then posted to its strand: a new operation). So the blocks cannot live in the
// connection. The connection holds a HandlerMemory::Owner, each wrapped handler a
// reference, and each block in use one more; the memory is freed when all are gone.
// allocate and deallocate may run on any thread.
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <memory>
#include <new>
#include <type_traits>
#include <utility>

#include "server/net/asio.hpp"

namespace vox::net {

class HandlerMemory {
 public:
  static constexpr size_t kBlocks = 4;
  static constexpr size_t kBlockBytes = 2048;

  struct Release {
    void operator()(HandlerMemory* m) const { m->unref(); }
  };
  using Owner = std::unique_ptr<HandlerMemory, Release>;
  static Owner make() { return Owner(new HandlerMemory); }

  void* allocate(size_t bytes) {
    if (bytes <= kBlockBytes) {
      for (Block& b : blocks_) {
        bool free = false;
        if (b.used.compare_exchange_strong(free, true, std::memory_order_acquire)) {
          refs_.fetch_add(1, std::memory_order_relaxed);
          return b.bytes;
        }
      }
    }
    return ::operator new(bytes);
  }

  void deallocate(void* p) {
    for (Block& b : blocks_) {
      if (p == b.bytes) {
        b.used.store(false, std::memory_order_release);
        unref();
        return;
      }
    }
    ::operator delete(p);
  }

  static constexpr size_t bytes() { return sizeof(HandlerMemory); }

  // A counted reference, held by each handler wrapped by `with_memory` (moves are free).
  class Ref {
   public:
    explicit Ref(HandlerMemory* m) : m_(m) { m_->refs_.fetch_add(1, std::memory_order_relaxed); }
    Ref(const Ref& o) : Ref(o.m_) {}
    Ref(Ref&& o) noexcept : m_(std::exchange(o.m_, nullptr)) {}
    Ref& operator=(Ref o) noexcept {
      std::swap(m_, o.m_);
      return *this;
    }
    ~Ref() {
      if (m_) m_->unref();
    }
    HandlerMemory* get() const { return m_; }

   private:
    HandlerMemory* m_;
  };

 private:
  HandlerMemory() = default;
  void unref() {
    if (refs_.fetch_sub(1, std::memory_order_acq_rel) == 1) delete this;
  }

  struct Block {
    alignas(std::max_align_t) unsigned char bytes[kBlockBytes];
    std::atomic<bool> used{false};
  };
  std::array<Block, kBlocks> blocks_;
  std::atomic<size_t> refs_{1};  // the owner, each handler's Ref and each block in use
};

template <class T>
class HandlerAllocator {
 public:
  using value_type = T;
  explicit HandlerAllocator(HandlerMemory* memory) : memory_(memory) {}
  template <class U>
  HandlerAllocator(const HandlerAllocator<U>& other) : memory_(other.memory_) {}
  T* allocate(size_t n) { return static_cast<T*>(memory_->allocate(sizeof(T) * n)); }
  void deallocate(T* p, size_t) { memory_->deallocate(p); }
  template <class U>
  bool operator==(const HandlerAllocator<U>& other) const {
    return memory_ == other.memory_;
  }

 private:
  template <class>
  friend class HandlerAllocator;
  HandlerMemory* memory_;
};

// `handler`, with its operations' memory from `memory` (its executor is the I/O object's).
template <class Handler>
class WithMemory {
 public:
  using allocator_type = HandlerAllocator<void>;
  WithMemory(HandlerMemory* memory, Handler handler)
      : memory_(memory), handler_(std::move(handler)) {}
  allocator_type get_allocator() const noexcept { return allocator_type(memory_.get()); }
  template <class... Args>
  void operator()(Args&&... args) {
    handler_(std::forward<Args>(args)...);
  }

 private:
  HandlerMemory::Ref memory_;  // alive while this handler is, whoever else let go of it
  Handler handler_;
};

template <class Handler>
WithMemory<std::decay_t<Handler>> with_memory(const HandlerMemory::Owner& memory,
                                              Handler&& handler) {
  return {memory.get(), std::forward<Handler>(handler)};
}

}  // namespace vox::net
