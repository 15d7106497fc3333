// The multi-rate lockstep of haptic ticks and tissue steps (runtime/src/session/
// step_schedule.h): which ticks hand a step over, which step each tick sends, the rate
// controller, and the trace notes that let a replay follow (lockstep_notes.h).

#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <vector>

#include "session/lockstep_notes.h"
#include "session/step_schedule.h"
#include "session/tissue_thread.h"

namespace bisturi::runtime {
namespace {

TEST(StepSchedule, OneTickPerStepIsThePlainLockstep) {
  for (std::uint32_t lag = 0; lag <= 4; ++lag) {
    StepSchedule s(lag, 1);
    for (std::uint64_t k = 1; k <= 100; ++k) {
      ASSERT_TRUE(s.hands_over(k)) << "tick " << k;
      EXPECT_EQ(s.handed_over_ticks(), 1u);
      EXPECT_EQ(s.due(k), scheduled_step(k, lag)) << "tick " << k << ", lag " << lag;
    }
    EXPECT_EQ(s.steps(), 100u);
  }
}

TEST(StepSchedule, ALongerStepGetsAsMuchMoreTime) {
  // Four ticks per step, lag 3: steps at ticks 4, 8, 12, ..., each due 3 + 3 ticks later.
  StepSchedule s(3, 4);
  std::vector<std::uint64_t> hand_overs;
  std::vector<std::uint64_t> due;
  for (std::uint64_t k = 1; k <= 20; ++k) {
    if (s.hands_over(k)) hand_overs.push_back(k);
    due.push_back(s.due(k));
  }
  EXPECT_EQ(hand_overs, (std::vector<std::uint64_t>{4, 8, 12, 16, 20}));
  EXPECT_EQ(due[8], 0u);   // tick 9
  EXPECT_EQ(due[9], 1u);   // tick 10 = 4 + 3 + 3
  EXPECT_EQ(due[13], 2u);  // tick 14
  EXPECT_EQ(due[19], 3u);  // tick 20: step 3 (tick 12) due at 18, step 4 (16) at 22
}

TEST(StepSchedule, ADroppedHandOverNeverComesDueAndTheNextTakesItsNumber) {
  // Lag 2, one tick per step: ticks 1..10 hand over; the tissue cannot take tick 5's step.
  StepSchedule s(2, 1);
  std::vector<std::uint64_t> due;
  for (std::uint64_t k = 1; k <= 10; ++k) {
    ASSERT_TRUE(s.hands_over(k));
    if (k == 5) s.forget_hand_over();
    due.push_back(s.due(k));
  }
  EXPECT_EQ(s.steps(), 9u);
  // Steps 1-4 from ticks 1-4 are due at 3-6; tick 5's step never comes; step 5 (from tick 6) is
  // due at tick 8: ticks 7 and 8 both send step 4, then 5, 6.
  EXPECT_EQ(due, (std::vector<std::uint64_t>{0, 0, 1, 2, 3, 4, 4, 5, 6, 7}));
}

TEST(StepSchedule, RateChangesKeepTheScheduleConsistent) {
  // Random changes among 1, 2, 4 and 8 ticks per step at hand-over ticks: every tick is covered
  // by exactly one step, each step is due no earlier than lag ticks after its hand-over, and
  // the step a tick sends never goes back.
  std::mt19937 rng(7);
  const std::uint32_t choices[] = {1, 2, 4, 8};
  for (std::uint32_t lag : {0u, 1u, 3u}) {
    StepSchedule s(lag, 1);
    std::uint64_t covered = 0, last_hand_over = 0, last_due = 0, changes = 0;
    std::vector<std::uint64_t> hand_over_of_step{0};
    for (std::uint64_t k = 1; k <= 5000; ++k) {
      if (s.hands_over(k)) {
        EXPECT_EQ(k - last_hand_over, s.handed_over_ticks()) << "tick " << k;
        covered += s.handed_over_ticks();
        last_hand_over = k;
        hand_over_of_step.push_back(k);
        if (rng() % 7 == 0) {
          s.set_ticks_per_step(k, choices[rng() % 4]);
          ++changes;
        }
      }
      const std::uint64_t d = s.due(k);
      EXPECT_GE(d, last_due);
      EXPECT_LE(d, s.steps());
      if (d > 0) {
        EXPECT_GE(k, hand_over_of_step[d] + lag);
      }
      last_due = d;
    }
    EXPECT_EQ(covered, last_hand_over);
    EXPECT_GT(changes, 50u);
  }
}

TEST(TissueRateController, HalvesTheRateWhenStepsTakeTooLongAndDoublesItWhenThereIsRoom) {
  TissueRateController c(1, 8, 1.0);
  // 0.9 ms steps at 1 ms per step: too long, but only after the pause that lets the median fill.
  for (int i = 0; i < 47; ++i)
    EXPECT_EQ(c.decide(0.9), 1u);
  EXPECT_EQ(c.decide(0.9), 2u);
  // At 2 ms per step 0.9 ms fits: no change, however long.
  for (int i = 0; i < 2000; ++i)
    ASSERT_EQ(c.decide(0.9), 2u);
  // Steps grow (a cut made the organ bigger): up to the limit and no further.
  std::uint32_t n = 2;
  for (int i = 0; i < 1000; ++i)
    n = c.decide(20.0);
  EXPECT_EQ(n, 8u);
  // Steps shrink again: back down, one halving per pause, to one tick per step.
  for (int i = 0; i < 1000; ++i)
    n = c.decide(0.1);
  EXPECT_EQ(n, 1u);
}

TEST(TissueRateController, ABladeSweepingHalvesAFullRateAtOnceAndHoldsItUntilTheSweepEnds) {
  TissueRateController c(1, 8, 1.0);
  // Cheap steps at one tick each; the blade enters: two ticks from the next step on.
  for (int i = 0; i < 300; ++i)
    ASSERT_EQ(c.decide(0.2), 1u);
  EXPECT_EQ(c.decide(0.2, true), 2u);
  // However cheap, not back to one tick while it sweeps.
  for (int i = 0; i < 2000; ++i)
    ASSERT_EQ(c.decide(0.2, true), 2u);
  // Slow steps still halve it further while cutting.
  std::uint32_t n = 2;
  for (int i = 0; i < 100; ++i)
    n = c.decide(1.8, true);
  EXPECT_EQ(n, 4u);
  // The sweep over and the steps cheap again: back to one tick, a halving per pause.
  for (int i = 0; i < 1000; ++i)
    n = c.decide(0.2);
  EXPECT_EQ(n, 1u);
  // A rate already at two ticks or fewer per step is left as it is; one that allows only one
  // tick per step (max_ticks 1) too.
  TissueRateController half(2, 8, 1.0);
  EXPECT_EQ(half.decide(0.2, true), 2u);
  TissueRateController only_one(1, 1, 1.0);
  EXPECT_EQ(only_one.decide(0.2, true), 1u);
}

TEST(TissueRateController, ALowerLoadLimitHalvesSooner) {
  TissueRateController tight(1, 8, 1.0, 0.25);
  TissueRateController loose(1, 8, 1.0, 0.75);
  std::uint32_t a = 1, b = 1;
  for (int i = 0; i < 48; ++i) {
    a = tight.decide(0.3);
    b = loose.decide(0.3);
  }
  EXPECT_EQ(a, 2u);
  EXPECT_EQ(b, 1u);
}

TEST(TissueRateController, FirstRateCoversTheStepAtTheLoadLimit) {
  // 1 ms ticks, steps may take 3/4 of their time.
  EXPECT_EQ(ticks_per_step_for(0.5, 1.0, 0.75, 8), 1u);
  EXPECT_EQ(ticks_per_step_for(0.75, 1.0, 0.75, 8), 1u);  // exactly at the limit still fits
  EXPECT_EQ(ticks_per_step_for(0.9, 1.0, 0.75, 8), 2u);
  EXPECT_EQ(ticks_per_step_for(3.3, 1.0, 0.75, 8), 8u);   // 6.5k-vertex organ, Zen 1
  EXPECT_EQ(ticks_per_step_for(50.0, 1.0, 0.75, 8), 8u);  // never past the most
  EXPECT_EQ(ticks_per_step_for(50.0, 1.0, 0.75, 6), 6u);
  EXPECT_EQ(ticks_per_step_for(0.9, 1.0, 0.75, 0), 1u);
}

TEST(LockstepNotes, RoundTripAndRefuseWhatTheyAreNot) {
  const auto l = parse_late_tick_note(late_tick_note(1234, 1229));
  ASSERT_TRUE(l.has_value());
  EXPECT_EQ(l->tick, 1234u);
  EXPECT_EQ(l->step, 1229u);
  const auto c = parse_tissue_rate_note(tissue_rate_note(4096, 4));
  ASSERT_TRUE(c.has_value());
  EXPECT_EQ(c->tick, 4096u);
  EXPECT_EQ(c->ticks_per_step, 4u);
  for (const char* other : {"tick", R"({"session_end": {"ticks": 3}})", "{", "[1, 2]"}) {
    EXPECT_FALSE(parse_late_tick_note(other).has_value()) << other;
    EXPECT_FALSE(parse_tissue_rate_note(other).has_value()) << other;
  }
  EXPECT_FALSE(parse_late_tick_note(tissue_rate_note(4096, 4)).has_value());
  EXPECT_FALSE(parse_tissue_rate_note(late_tick_note(3, 2)).has_value());
  EXPECT_FALSE(parse_late_tick_note(R"({"late_tick": {"tick": -1, "step": 2}})").has_value());
  EXPECT_FALSE(parse_tissue_rate_note(R"({"tissue_rate": {"tick": 5, "ticks_per_step": 0}})"));
  EXPECT_FALSE(parse_tissue_rate_note(R"({"tissue_rate": {"tick": -5, "ticks_per_step": 2}})"));
  for (const bool held : {true, false}) {
    const auto b = parse_blood_hold_note(blood_hold_note(777, held));
    ASSERT_TRUE(b.has_value());
    EXPECT_EQ(b->tick, 777u);
    EXPECT_EQ(b->held, held);
  }
  EXPECT_FALSE(parse_blood_hold_note(tissue_rate_note(4096, 1)).has_value());
  EXPECT_FALSE(parse_tissue_rate_note(blood_hold_note(4096, true)).has_value());
  EXPECT_FALSE(parse_blood_hold_note(R"({"blood_hold": {"tick": 5, "held": 2}})").has_value());
}

}  // namespace
}  // namespace bisturi::runtime
