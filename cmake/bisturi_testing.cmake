# GoogleTest programs register their tests through bisturi_discover_tests, which labels them:
# `quick` (the inner loop: `ctest -L quick`) or `slow` (the programs listed below, which run
# sessions in real time or long random runs). Other tests carry `cli`, `session`, `fuzz` or
# `slurm` (tests/CMakeLists.txt). A plain `ctest` runs every label.
include(GoogleTest)

# Programs with a test that takes more than about 10 s on the 2-core machine (ctest's
# CTestCostData.txt after a run): dlfl_random_test's 100,000 random operator calls (about 20 s).
set(BISTURI_SLOW_UNIT_TESTS dlfl_random_test)

function(bisturi_discover_tests target)
  set(label quick)
  if(target IN_LIST BISTURI_SLOW_UNIT_TESTS)
    set(label slow)
  endif()
  gtest_discover_tests(${target} DISCOVERY_TIMEOUT 60 PROPERTIES LABELS ${label})
endfunction()
