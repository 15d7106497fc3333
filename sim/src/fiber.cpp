// Fibers on ucontext (see fiber.h).

#include "fiber.h"

#include <stdexcept>
#include <utility>

#include <sys/mman.h>
#include <unistd.h>

#if defined(__SANITIZE_ADDRESS__)
#include <sanitizer/common_interface_defs.h>
#define BISTURI_FIBER_ASAN 1
#endif

namespace bisturi::sim {
namespace {

thread_local Fiber* t_current = nullptr;

// AddressSanitizer must be told when the stack changes (no-ops without it).
void start_switch([[maybe_unused]] void** fake_stack_save, [[maybe_unused]] const void* bottom,
                  [[maybe_unused]] std::size_t size) {
#ifdef BISTURI_FIBER_ASAN
  __sanitizer_start_switch_fiber(fake_stack_save, bottom, size);
#endif
}
void finish_switch([[maybe_unused]] void* fake_stack_save, [[maybe_unused]] const void** bottom_old,
                   [[maybe_unused]] std::size_t* size_old) {
#ifdef BISTURI_FIBER_ASAN
  __sanitizer_finish_switch_fiber(fake_stack_save, bottom_old, size_old);
#endif
}

}  // namespace

Fiber::Fiber(std::size_t stack_bytes) {
  const auto page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  stack_bytes_ = (stack_bytes + page - 1) / page * page;
  mapping_bytes_ = stack_bytes_ + page;
  void* m =
      mmap(nullptr, mapping_bytes_, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (m == MAP_FAILED) throw std::runtime_error("fiber: cannot map a stack");
  mapping_ = static_cast<char*>(m);
  // The stack grows down: an overflow faults on the guard page instead of writing the heap.
  mprotect(mapping_, page, PROT_NONE);
}

Fiber::~Fiber() {
  while (part_way()) {
    try {
      resume();
    } catch (...) {  // NOLINT(bugprone-empty-catch): nobody is left to take it
    }
  }
  munmap(mapping_, mapping_bytes_);
}

void Fiber::start(std::function<void()> body) {
  if (part_way()) throw std::logic_error("fiber: started while part-way");
  body_ = std::move(body);
  error_ = nullptr;
  getcontext(&context_);
  context_.uc_stack.ss_sp = mapping_ + (mapping_bytes_ - stack_bytes_);
  context_.uc_stack.ss_size = stack_bytes_;
  context_.uc_link = nullptr;  // entry() switches back itself
  makecontext(&context_, &Fiber::entry, 0);
  started_ = true;
  finished_ = false;
}

bool Fiber::resume() {
  if (!part_way()) return true;
  outer_ = t_current;
  t_current = this;
  start_switch(&fake_stack_, mapping_ + (mapping_bytes_ - stack_bytes_), stack_bytes_);
  swapcontext(&caller_, &context_);
  finish_switch(fake_stack_, nullptr, nullptr);
  t_current = outer_;
  if (finished_ && error_) std::rethrow_exception(std::exchange(error_, nullptr));
  return finished_;
}

void Fiber::suspend() {
  Fiber* self = t_current;
  if (self == nullptr) throw std::logic_error("fiber: suspend outside a fiber");
  void* fake = nullptr;
  start_switch(&fake, self->caller_bottom_, self->caller_size_);
  swapcontext(&self->context_, &self->caller_);
  finish_switch(fake, &self->caller_bottom_, &self->caller_size_);
}

Fiber* Fiber::current() {
  return t_current;
}

void Fiber::entry() {
  Fiber* self = t_current;
  finish_switch(nullptr, &self->caller_bottom_, &self->caller_size_);
  try {
    self->body_();
  } catch (...) {
    self->error_ = std::current_exception();
  }
  self->body_ = nullptr;
  self->finished_ = true;
  // The function is done: its stack is dropped (nullptr), and the caller goes on.
  start_switch(nullptr, self->caller_bottom_, self->caller_size_);
  swapcontext(&self->context_, &self->caller_);
}

}  // namespace bisturi::sim
