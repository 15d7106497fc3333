#pragma once
// How the process's heap gives memory back to the kernel. A program that renders frames calls
// keep_freed_heap() once, at its start.

#include <cstddef>

namespace bisturi::runtime {

/// Keeps freed heap memory in the process for the next allocation instead of giving it back to
/// the kernel as soon as 128 KiB lie free at the top of a thread's heap (glibc's default).
/// lavapipe, drawing on the CPU, allocates and frees megabytes per draw on the render thread:
/// with the default, every frame faults those pages in again, zeroed and charged to the
/// container's memory cgroup one by one, which on the 2-core machine halved the bleeding scene's
/// frame rate. The heap's peak is unchanged; what the frames free is reused. Blocks of 32 MiB and
/// more are still mapped and unmapped on their own. Returns false where the C library refused.
bool keep_freed_heap();

/// Faults `bytes` of the calling thread's heap in, then frees them. With keep_freed_heap() in
/// force the pages stay in the thread's heap, so its later allocations, up to about that much
/// live at once, take no page faults: the Linux real-time guidance of faulting memory in before a
/// thread's loop starts. The tissue thread calls it as it starts: the step that makes a cut
/// builds a new lattice and its matrix, and took some 460 page faults (a fifth of that step on
/// the 2-core machine) while the haptic force waited for it.
void prefault_thread_heap(std::size_t bytes);

}  // namespace bisturi::runtime
