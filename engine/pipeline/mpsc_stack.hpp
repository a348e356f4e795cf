// A lock-free multi-producer, single-consumer hand-off of intrusive nodes: producers push with a
// CAS on the head; the one consumer takes everything at once with an exchange, so there is no ABA
// problem and no allocation. Order is not preserved (the consumer reorders by sequence number).
#pragma once

#include <atomic>

namespace stampede {

template <class Node>  // Node has a member `Node* next`
class MpscStack {
 public:
  void push(Node* node) {
    Node* head = head_.load(std::memory_order_relaxed);
    do {
      node->next = head;
    } while (!head_.compare_exchange_weak(head, node, std::memory_order_release, std::memory_order_relaxed));
    signal_.fetch_add(1, std::memory_order_release);
    signal_.notify_one();
  }
  // Everything pushed so far (most recent first), or null.
  Node* take_all() { return head_.exchange(nullptr, std::memory_order_acquire); }
  // A counter that changes on every push: load it, drain, then wait(value) sleeps until a push.
  unsigned long long signal() const { return signal_.load(std::memory_order_acquire); }
  void wait(unsigned long long seen) const { signal_.wait(seen, std::memory_order_acquire); }
  // Wakes the consumer without a node (shutdown).
  void poke() {
    signal_.fetch_add(1, std::memory_order_release);
    signal_.notify_one();
  }

 private:
  std::atomic<Node*> head_{nullptr};
  std::atomic<unsigned long long> signal_{0};
};

}  // namespace stampede
