// `odvr render` and `odvr bench render` take the renderer's switches from one declaration
// (app/flags/render_switches.h): each flag must reach its RenderOptions field, a value out of range
// must be refused naming the flag, and a bench's table must name exactly the flags it ran with.
#include "app/flags/render_switches.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

namespace odvr::app {
namespace {

render::RenderOptions Parse(std::vector<std::string> args) {
  CLI::App cli("render switches");
  render::RenderOptions options;
  AddRenderSwitches(&cli, &options);
  std::reverse(args.begin(), args.end());  // CLI11 takes the arguments last first
  cli.parse(args);
  return options;
}

TEST(RenderSwitches, NoFlagLeavesEveryDefaultAndNamesNothing) {
  const render::RenderOptions parsed = Parse({}), defaults;
  EXPECT_EQ(RenderSwitchesJson(parsed), RenderSwitchesJson(defaults));
  EXPECT_TRUE(NonDefaultRenderSwitches(parsed).empty());
}

TEST(RenderSwitches, EachFlagReachesItsFieldAndIsNamedBack) {
  const std::vector<std::string> args = {"--bin-depth",
                                         "--overlap-cutoff",
                                         "0.001",
                                         "--ground-lit-map",
                                         "0",
                                         "--peak-cone-shadows",
                                         "--raw-normals",
                                         "--no-specular-bounce",
                                         "--no-ambient-bounce",
                                         "--shading-rate",
                                         "2"};
  const render::RenderOptions o = Parse(args);
  const render::RenderOptions d;
  EXPECT_NE(o.depth_per_lobe, d.depth_per_lobe);
  EXPECT_FALSE(o.depth_per_lobe);
  EXPECT_DOUBLE_EQ(o.overlap_cutoff, 0.001);
  EXPECT_EQ(o.ground_lit_map_texels, 0);
  EXPECT_FALSE(o.exact_peak_shadows);
  EXPECT_FALSE(o.valid_reflection_normals);
  EXPECT_FALSE(o.specular_bounce);
  EXPECT_FALSE(o.ambient_bounce);
  EXPECT_EQ(o.shading_rate, 2);
  const nlohmann::json j = RenderSwitchesJson(o);
  EXPECT_FALSE(j.at("depth_per_lobe").get<bool>());
  EXPECT_EQ(j.at("shading_rate").get<int>(), 2);
  EXPECT_EQ(j.size(), 8u);
  // Named back as flags that parse to the same options: a bench's header says how to rerun it.
  std::vector<std::string> named;
  for (const std::string& flag : NonDefaultRenderSwitches(o)) {
    const auto space = flag.find(' ');
    named.push_back(flag.substr(0, space));
    if (space != std::string::npos) named.push_back(flag.substr(space + 1));
  }
  EXPECT_EQ(NonDefaultRenderSwitches(o).size(), 8u);
  EXPECT_EQ(RenderSwitchesJson(Parse(named)), j);
}

TEST(RenderSwitches, ValuesOutOfRangeAreRefusedNamingTheFlag) {
  for (const std::vector<std::string>& bad : std::vector<std::vector<std::string>>{
           {"--overlap-cutoff", "0"}, {"--ground-lit-map", "4"}, {"--shading-rate", "3"}}) {
    try {
      Parse(bad);
      ADD_FAILURE() << bad[0] << " " << bad[1] << " was taken";
    } catch (const CLI::ParseError& e) {
      EXPECT_NE(std::string(e.what()).find(bad[0]), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace odvr::app
