// ParseMaterialOverride (app/flags/material_flag.h): every BRDF model's form, the KD,KS,N
// shorthand, and the texts it refuses.
#include "app/flags/material_flag.h"

#include <gtest/gtest.h>

#include <string>
#include <variant>

#include "core/error.h"
#include "engine/material/brdf.h"

namespace odvr::app {
namespace {

TEST(MaterialFlag, ParsesEveryModelAndTheKdKsNForm) {
  const render::MaterialOverride a = ParseMaterialOverride("paint=0.3,0.6,200");
  EXPECT_EQ(a.material, "paint");
  ASSERT_EQ(a.brdfs.size(), 2u);
  EXPECT_DOUBLE_EQ(std::get<material::Lambertian>(a.brdfs[0]).albedo.x, 0.3);
  EXPECT_DOUBLE_EQ(std::get<material::Phong>(a.brdfs[1]).exponent, 200);
  const render::MaterialOverride b = ParseMaterialOverride("lambert:0.5,0.4,0.3+ct:0.9,0.8,0.7,0.1,beckmann");
  EXPECT_TRUE(b.material.empty());
  ASSERT_EQ(b.brdfs.size(), 2u);
  EXPECT_EQ(std::get<material::CookTorrance>(b.brdfs[1]).ndf, material::Ndf::kBeckmann);
  const render::MaterialOverride c = ParseMaterialOverride("glass=mr:0.1,0.1,0.1,0,0.05");
  EXPECT_DOUBLE_EQ(std::get<material::MetallicRoughness>(c.brdfs[0]).roughness, 0.05);
  for (const char* bad : {"", "paint=", "1,2", "0.7,0.6,10", "lambert:1,1", "phong:1,1,1,-1", "foo:1,2,3",
                          "ward:1,1,1,0", "lambert:1,1,x", "lambert:1,1,1+lambert:1,1,1+lambert:1,1,1"})
    EXPECT_THROW(ParseMaterialOverride(bad), UsageError) << bad;
}

// The values' ranges are material::CheckBrdf's, reported as a usage error naming the text: the
// bounds themselves are accepted, a step past them (or NaN, which no range contains) is not.
TEST(MaterialFlag, RefusesAValueOutOfItsRangeNamingTheText) {
  for (const char* good : {"mr:1,1,1,1,0", "mr:0,0,0,0,1", "phong:1,1,1,0", "phong:1,1,1,100000", "blinn:0,0,0,0",
                           "ward:1,1,1,1", "ct:1,1,1,0.000001,beckmann", "0,1,100000", "1,0,0"})
    EXPECT_NO_THROW(ParseMaterialOverride(good)) << good;
  for (const char* bad :
       {"mr:1.01,1,1,1,0", "mr:0,0,0,-0.01,1", "mr:0,0,0,0,1.5", "phong:1,1,1,100001", "blinn:1,1,1,-1", "ward:1,1,1,0",
        "ward:1,1,1,1.01", "ct:1,1,1,0", "ct:-0.1,0,0,0.5", "0.6,0.5,10", "lambert:nan,0,0", "0,1,-1"}) {
    try {
      ParseMaterialOverride(bad);
      ADD_FAILURE() << bad << " accepted";
    } catch (const UsageError& e) {
      EXPECT_NE(std::string(e.what()).find(std::string("--material ") + bad), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace odvr::app
