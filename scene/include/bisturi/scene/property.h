#pragma once
// Per-element attribute arrays (struct of arrays) that algorithms attach to a Dlfl by name. The
// Dlfl keeps every registered array the size of its element array: a created element gets the
// array's default value, and compact() renumbers the arrays together with the elements, so data
// attached to a vertex (a mass, a spring rest length) can never outlive or miss its vertex.

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "bisturi/scene/errors.h"
#include "bisturi/scene/handles.h"

namespace bisturi {

/// Type-erased interface the Dlfl uses to keep an array in step with its elements.
class PropertyArrayBase {
 public:
  virtual ~PropertyArrayBase() = default;
  /// Grows (or shrinks) to n entries; new entries take the default value.
  virtual void resize(std::size_t n) = 0;
  /// Makes room for n entries without changing the size (growth then copies nothing).
  virtual void reserve(std::size_t n) = 0;
  /// Puts the default value at i (an element slot is being reused).
  virtual void reset(std::uint32_t i) = 0;
  /// Keeps entry old at new_index[old] for every old entry whose new_index is valid.
  virtual void renumber(const std::vector<std::uint32_t>& new_index, std::size_t new_size) = 0;
  /// A deep copy (for copying a whole mesh).
  [[nodiscard]] virtual std::unique_ptr<PropertyArrayBase> clone() const = 0;
};

/// One attribute per element, indexed by that element's handle.
template <class Tag, class T>
class PropertyArray final : public PropertyArrayBase {
 public:
  PropertyArray(std::size_t n, T default_value) : default_(std::move(default_value)) {
    data_.assign(n, default_);
  }

  T& operator[](Handle<Tag> h) { return data_[h.idx]; }
  const T& operator[](Handle<Tag> h) const { return data_[h.idx]; }
  [[nodiscard]] std::size_t size() const { return data_.size(); }
  std::vector<T>& raw() { return data_; }
  const std::vector<T>& raw() const { return data_; }

  void resize(std::size_t n) override { data_.resize(n, default_); }
  void reserve(std::size_t n) override { data_.reserve(n); }
  void reset(std::uint32_t i) override { data_[i] = default_; }
  void renumber(const std::vector<std::uint32_t>& new_index, std::size_t new_size) override {
    std::vector<T> out(new_size, default_);
    for (std::size_t old = 0; old < new_index.size() && old < data_.size(); ++old) {
      if (new_index[old] != kInvalidIndex) out[new_index[old]] = std::move(data_[old]);
    }
    data_ = std::move(out);
  }
  [[nodiscard]] std::unique_ptr<PropertyArrayBase> clone() const override {
    return std::make_unique<PropertyArray>(*this);
  }

 private:
  std::vector<T> data_;
  T default_;
};

/// The named arrays attached to one kind of element.
template <class Tag>
class PropertyRegistry {
 public:
  PropertyRegistry() = default;
  /// Copies every array (references into the source stay with the source).
  PropertyRegistry(const PropertyRegistry& other) : size_(other.size_) {
    for (const auto& [name, a] : other.arrays_)
      arrays_.emplace(name, a->clone());
  }
  PropertyRegistry& operator=(const PropertyRegistry& other) {
    if (this != &other) *this = PropertyRegistry(other);
    return *this;
  }
  PropertyRegistry(PropertyRegistry&&) noexcept = default;
  PropertyRegistry& operator=(PropertyRegistry&&) noexcept = default;
  ~PropertyRegistry() = default;
  /// Adds an array named `name` (throws if the name is taken). The reference stays valid until
  /// the array is removed.
  template <class T>
  PropertyArray<Tag, T>& add(const std::string& name, T default_value = T{}) {
    if (arrays_.count(name) != 0) {
      throw TopologyError("property '" + name + "' already exists");
    }
    auto array = std::make_unique<PropertyArray<Tag, T>>(size_, std::move(default_value));
    auto& ref = *array;
    arrays_.emplace(name, std::move(array));
    return ref;
  }

  /// The array named `name` with element type T (throws if missing or of another type).
  template <class T>
  PropertyArray<Tag, T>& get(const std::string& name) {
    auto it = arrays_.find(name);
    if (it == arrays_.end()) throw TopologyError("no property named '" + name + "'");
    auto* typed = dynamic_cast<PropertyArray<Tag, T>*>(it->second.get());
    if (typed == nullptr) throw TopologyError("property '" + name + "' has another type");
    return *typed;
  }

  /// The same, read only.
  template <class T>
  const PropertyArray<Tag, T>& get(const std::string& name) const {
    return const_cast<PropertyRegistry*>(this)->get<T>(name);
  }

  [[nodiscard]] bool has(const std::string& name) const { return arrays_.count(name) != 0; }
  void remove(const std::string& name) { arrays_.erase(name); }
  [[nodiscard]] std::size_t count() const { return arrays_.size(); }

  // Called by the Dlfl only.
  void resize(std::size_t n) {
    size_ = n;
    for (auto& [name, a] : arrays_)
      a->resize(n);
  }
  void reserve(std::size_t n) {
    for (auto& [name, a] : arrays_)
      a->reserve(n);
  }
  void reset(std::uint32_t i) {
    for (auto& [name, a] : arrays_)
      a->reset(i);
  }
  void renumber(const std::vector<std::uint32_t>& new_index, std::size_t new_size) {
    size_ = new_size;
    for (auto& [name, a] : arrays_)
      a->renumber(new_index, new_size);
  }

 private:
  std::size_t size_ = 0;
  std::map<std::string, std::unique_ptr<PropertyArrayBase>> arrays_;
};

}  // namespace bisturi
