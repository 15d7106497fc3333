#pragma once
// Shared by the benchmark programs: a reporter that prints the usual table and keeps every run,
// so that a summary with ratios measured in the same run can follow it.

#include <benchmark/benchmark.h>

#include <map>
#include <memory>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

namespace bisturi::bench {

/// Passes every run to the reporter chosen by --benchmark_format and keeps them for the summary.
class CollectingReporter : public benchmark::BenchmarkReporter {
 public:
  CollectingReporter() : inner_(benchmark::CreateDefaultDisplayReporter()) {}

  bool ReportContext(const Context& context) override {
    inner_->SetOutputStream(&GetOutputStream());
    inner_->SetErrorStream(&GetErrorStream());
    return inner_->ReportContext(context);
  }
  void ReportRuns(const std::vector<Run>& runs) override {
    for (const Run& run : runs) {
      if (run.run_type == Run::RT_Iteration && !run.error_occurred) {
        runs_[run.benchmark_name()] = run;
      }
    }
    inner_->ReportRuns(runs);
  }
  void Finalize() override { inner_->Finalize(); }

  [[nodiscard]] bool empty() const { return runs_.empty(); }

  /// The summary goes with the table on the console, to stderr when stdout holds JSON or CSV.
  std::ostream& summary_stream() {
    return dynamic_cast<benchmark::ConsoleReporter*>(inner_.get()) != nullptr ? GetOutputStream()
                                                                              : GetErrorStream();
  }
  /// The run named `name`, or `name/...` (Google Benchmark appends /manual_time, /iterations:N).
  const Run* find(const std::string& name) const {
    auto it = runs_.lower_bound(name);
    if (it == runs_.end()) return nullptr;
    if (it->first == name || it->first.rfind(name + "/", 0) == 0) return &it->second;
    return nullptr;
  }
  std::optional<double> counter(const std::string& name, const std::string& key) const {
    const Run* run = find(name);
    if (run == nullptr) return std::nullopt;
    auto it = run->counters.find(key);
    if (it == run->counters.end()) return std::nullopt;
    return it->second.value;
  }

 private:
  std::unique_ptr<benchmark::BenchmarkReporter> inner_;
  std::map<std::string, Run> runs_;
};

}  // namespace bisturi::bench
