// The loader's side of the runtime: negotiation (the only exported symbol; xrGetInstanceProcAddr
// is handed over through it, never exported, since the loader's own xrGetInstanceProcAddr would
// otherwise interpose and call itself), the handle registry and helpers shared by the entry points.

#include <chrono>
#include <cstring>
#include <mutex>
#include <string_view>
#include <unordered_set>

#include "api.h"

// Declared in the loader's runtime interface (not shipped in Debian's libopenxr-dev 1.0.20);
// laid out as the loader's loader_interfaces.h lays them out.
extern "C" {
enum XrLoaderInterfaceStructs {
  XR_LOADER_INTERFACE_STRUCT_UNINTIALIZED = 0,
  XR_LOADER_INTERFACE_STRUCT_LOADER_INFO = 1,
  XR_LOADER_INTERFACE_STRUCT_API_LAYER_REQUEST = 2,
  XR_LOADER_INTERFACE_STRUCT_RUNTIME_REQUEST = 3,
};
struct XrNegotiateLoaderInfo {
  XrLoaderInterfaceStructs structType;
  std::uint32_t structVersion;
  std::size_t structSize;
  std::uint32_t minInterfaceVersion;
  std::uint32_t maxInterfaceVersion;
  XrVersion minApiVersion;
  XrVersion maxApiVersion;
};
struct XrNegotiateRuntimeRequest {
  XrLoaderInterfaceStructs structType;
  std::uint32_t structVersion;
  std::size_t structSize;
  std::uint32_t runtimeInterfaceVersion;
  XrVersion runtimeApiVersion;
  PFN_xrGetInstanceProcAddr getInstanceProcAddr;
};

__attribute__((visibility("default"))) XrResult xrNegotiateLoaderRuntimeInterface(
    const XrNegotiateLoaderInfo* loader, XrNegotiateRuntimeRequest* runtime);
}

namespace bisturi::xrsim {

XrResult XRAPI_CALL GetInstanceProcAddr(XrInstance instance, const char* name,
                                        PFN_xrVoidFunction* function);

namespace {

constexpr std::uint32_t kInterfaceVersion = 1;  // the loader-runtime interface, version 1

template <typename F>
struct Unsupported;
template <typename... A>
struct Unsupported<XrResult(XRAPI_PTR*)(A...)> {
  static XrResult XRAPI_CALL call(A...) { return XR_ERROR_FUNCTION_UNSUPPORTED; }
};

/// The extension an entry point belongs to: it is found only once the instance enabled it.
enum class Needs : std::uint8_t { Core, Vulkan2, Timespec };

struct Entry {
  std::string_view name;
  PFN_xrVoidFunction function;
  Needs needs;
};

#define BISTURI_XRSIM_ENTRY(name) \
  Entry{"xr" #name, reinterpret_cast<PFN_xrVoidFunction>(&name), Needs::Core},
#define BISTURI_XRSIM_ENTRY_VK(name) \
  Entry{"xr" #name, reinterpret_cast<PFN_xrVoidFunction>(&name), Needs::Vulkan2},
#define BISTURI_XRSIM_ENTRY_TS(name) \
  Entry{"xr" #name, reinterpret_cast<PFN_xrVoidFunction>(&name), Needs::Timespec},
#define BISTURI_XRSIM_ENTRY_UNSUPPORTED(name)                                               \
  Entry{"xr" #name, reinterpret_cast<PFN_xrVoidFunction>(&Unsupported<PFN_xr##name>::call), \
        Needs::Core},

const Entry kEntries[] = {
    Entry{"xrGetInstanceProcAddr", reinterpret_cast<PFN_xrVoidFunction>(&GetInstanceProcAddr),
          Needs::Core},
    BISTURI_XRSIM_CORE(BISTURI_XRSIM_ENTRY) BISTURI_XRSIM_VULKAN(BISTURI_XRSIM_ENTRY_VK)
        BISTURI_XRSIM_TIMESPEC(BISTURI_XRSIM_ENTRY_TS)
            BISTURI_XRSIM_UNSUPPORTED(BISTURI_XRSIM_ENTRY_UNSUPPORTED)};

std::mutex registry_mutex;
std::unordered_set<const void*>& registry() {
  static std::unordered_set<const void*> objects;
  return objects;
}

}  // namespace

bool live(const void* object) {
  const std::lock_guard<std::mutex> lock(registry_mutex);
  return object != nullptr && registry().count(object) > 0;
}
void track(const void* object) {
  const std::lock_guard<std::mutex> lock(registry_mutex);
  registry().insert(object);
}
void untrack(const void* object) {
  const std::lock_guard<std::mutex> lock(registry_mutex);
  registry().erase(object);
}

std::int64_t now_ns() {
  // XrTime here is CLOCK_MONOTONIC (what XR_KHR_convert_timespec_time converts from).
  timespec t{};
  clock_gettime(CLOCK_MONOTONIC, &t);
  return static_cast<std::int64_t>(t.tv_sec) * 1'000'000'000 + t.tv_nsec;
}

const char* state_name(XrSessionState state) {
  switch (state) {
#define BISTURI_XRSIM_STATE(name, value) \
  case name:                             \
    return #name;
    XR_LIST_ENUM_XrSessionState(BISTURI_XRSIM_STATE)
#undef BISTURI_XRSIM_STATE
        default : return "XR_SESSION_STATE_?";
  }
}

}  // namespace bisturi::xrsim

using namespace bisturi::xrsim;

XrResult xrNegotiateLoaderRuntimeInterface(const XrNegotiateLoaderInfo* loader,
                                           XrNegotiateRuntimeRequest* runtime) {
  if (loader == nullptr || runtime == nullptr ||
      loader->structType != XR_LOADER_INTERFACE_STRUCT_LOADER_INFO ||
      runtime->structType != XR_LOADER_INTERFACE_STRUCT_RUNTIME_REQUEST ||
      runtime->structSize < sizeof(XrNegotiateRuntimeRequest)) {
    return XR_ERROR_INITIALIZATION_FAILED;
  }
  if (loader->minInterfaceVersion > kInterfaceVersion ||
      loader->maxInterfaceVersion < kInterfaceVersion ||
      XR_VERSION_MAJOR(loader->maxApiVersion) < 1 || XR_VERSION_MAJOR(loader->minApiVersion) > 1) {
    return XR_ERROR_INITIALIZATION_FAILED;
  }
  runtime->runtimeInterfaceVersion = kInterfaceVersion;
  runtime->runtimeApiVersion = XR_CURRENT_API_VERSION;
  runtime->getInstanceProcAddr = &GetInstanceProcAddr;
  return XR_SUCCESS;
}

XrResult XRAPI_CALL bisturi::xrsim::GetInstanceProcAddr(XrInstance instance, const char* name,
                                                        PFN_xrVoidFunction* function) {
  if (name == nullptr || function == nullptr) return XR_ERROR_VALIDATION_FAILURE;
  *function = nullptr;
  const std::string_view wanted(name);
  // Without an instance only these may be asked for (the specification's rule).
  if (instance == XR_NULL_HANDLE && wanted != "xrEnumerateInstanceExtensionProperties" &&
      wanted != "xrEnumerateApiLayerProperties" && wanted != "xrCreateInstance") {
    return XR_ERROR_HANDLE_INVALID;
  }
  const Instance* owner = object<Instance>(instance);
  if (instance != XR_NULL_HANDLE && owner == nullptr) return XR_ERROR_HANDLE_INVALID;
  for (const Entry& e : kEntries) {
    if (e.name == wanted) {
      const bool enabled = e.needs == Needs::Core ||
                           (owner != nullptr &&
                            (e.needs == Needs::Vulkan2 ? owner->vulkan2 : owner->convert_timespec));
      if (!enabled) return XR_ERROR_FUNCTION_UNSUPPORTED;
      *function = e.function;
      return XR_SUCCESS;
    }
  }
  return XR_ERROR_FUNCTION_UNSUPPORTED;
}
