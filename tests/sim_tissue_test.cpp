// Tissue in physical units: the presets exist with sources and valid parameters, the
// calibration follows the membrane and bulk formulas, and bad parameters are named.

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "bisturi/sim/errors.h"
#include "bisturi/sim/tissue.h"

namespace bisturi::sim {
namespace {

TEST(SimTissue, PresetsHaveSourcesAndValidParameters) {
  for (const char* name : {"liver", "kidney", "spleen", "vessel-wall", "fat"}) {
    const TissuePreset& p = tissue_preset(name);
    EXPECT_EQ(p.name, name);
    EXPECT_FALSE(p.source.empty()) << name;
    EXPECT_NO_THROW(check_elastic(p.material)) << name;
  }
  EXPECT_EQ(tissue_presets().size(), 5u);
  try {
    (void)tissue_preset("brain");
    FAIL() << "no brain preset";
  } catch (const SimInputError& e) {
    EXPECT_NE(std::string(e.what()).find("liver"), std::string::npos) << e.what();
  }
}

TEST(SimTissue, CalibrationFollowsTheMembraneAndBulkFormulas) {
  ElasticMaterial m;
  m.youngs_modulus_kPa = 5.0;
  m.poisson_ratio = 0.4;
  m.density_kg_per_m3 = 1000.0;
  m.retardation_time_s = 0.02;
  const Material a = calibrate_surface(m, 0.003);
  EXPECT_NEAR(a.structural_N_per_m, std::sqrt(3.0) / 2.0 * 5e3 * 0.003, 1e-12);
  EXPECT_NEAR(a.bulk_modulus_Pa, 5e3 / (3.0 * 0.2), 1e-9);
  EXPECT_NEAR(a.spring_damping_N_s_per_m, a.structural_N_per_m * 0.02, 1e-15);
  EXPECT_EQ(a.density_kg_per_m3, 1000.0);
  // Twice the modulus, twice every spring; the volume term follows.
  m.youngs_modulus_kPa = 10.0;
  const Material b = calibrate_surface(m, 0.003);
  EXPECT_NEAR(b.structural_N_per_m, 2.0 * a.structural_N_per_m, 1e-12);
  EXPECT_NEAR(b.shear_N_per_m, 2.0 * a.shear_N_per_m, 1e-12);
  EXPECT_NEAR(b.bending_N_per_m, 2.0 * a.bending_N_per_m, 1e-12);
  EXPECT_NEAR(b.bulk_modulus_Pa, 2.0 * a.bulk_modulus_Pa, 1e-9);
  // Nearly incompressible: a stiff volume term.
  m.poisson_ratio = 0.49;
  EXPECT_GT(calibrate_surface(m).bulk_modulus_Pa, 50.0 * 10e3 / 3.0 * 0.99);
}

TEST(SimTissue, BadParametersAreNamed) {
  auto message = [](const ElasticMaterial& m) {
    try {
      (void)calibrate_surface(m);
    } catch (const SimInputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  ElasticMaterial m;
  m.poisson_ratio = 0.5;
  EXPECT_NE(message(m).find("poisson_ratio"), std::string::npos);
  m = {};
  m.youngs_modulus_kPa = -1.0;
  EXPECT_NE(message(m).find("youngs_modulus_kPa"), std::string::npos);
  m = {};
  m.retardation_time_s = std::nan("");
  EXPECT_NE(message(m).find("retardation_time_s"), std::string::npos);
  EXPECT_THROW((void)calibrate_surface(ElasticMaterial{}, 0.0), SimInputError);
}

}  // namespace
}  // namespace bisturi::sim
