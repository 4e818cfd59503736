// The grid's channel sets declared once (engine/grid_channels.h): the table is consistent, the memory plan and
// --check's figures follow from it, and the developer guide's recipe quotes the declarations as they are.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>

#include "engine/grid_channels.h"
#include "engine/memory_plan.h"

namespace fbar {
namespace {

// Per-block GPU bytes written out by hand from the buffers' layouts (fixed-point sums: 8 bytes a value on float
// grids, 16 on double grids; values: the grid scalar): two P2G grids of 4 sums, a velocity of 3 values, ASFLIP's
// two transported grids of 3 sums and v^n of 3 values, F-bar's 2 sums, the seepage channels' 5 values and 5 sums.
std::size_t by_hand(Precision p, GridFeatures f) {
  const std::size_t sum = p == Precision::Double ? 16 : 8, tg = p == Precision::Double ? 8 : 4;
  std::size_t b = 2 * 4 * 64 * sum + 3 * 64 * tg;
  if (f.asflip) b += 2 * 3 * 64 * sum + 3 * 64 * tg;
  if (f.fbar) b += 2 * 64 * sum;
  if (f.pore) b += 5 * 64 * (tg + sum);
  return b;
}

TEST(GridChannels, BlockBytesFollowTheDeclarations) {
  for (Precision p : {Precision::Single, Precision::Double, Precision::Mixed})
    for (int mask = 0; mask < 8; ++mask) {
      const GridFeatures f{(mask & 1) != 0, (mask & 2) != 0, (mask & 4) != 0};
      EXPECT_EQ(grid_channel_block_bytes(p, f), by_hand(p, f)) << "precision " << static_cast<int>(p) << " mask " << mask;
    }
  EXPECT_EQ(cpu_grid_channels(GridFeatures{}), 4);
  EXPECT_EQ(cpu_grid_channels(GridFeatures{true, true, true}), 4 + 3 + 2 + 5);
}

// The plan's grid is the table plus capacity x the sets' block bytes; a growth adds the doubled grid and the largest
// one copy of a set (alive beside its bigger copy).
TEST(GridChannels, MemoryPlanSizesTheDeclaredSets) {
  for (Precision p : {Precision::Single, Precision::Double})
    for (bool pore : {false, true}) {
      BodyMemoryInput body;
      body.particles = 1000;
      body.bins_needed = 40;
      body.stored_scalars = 12;
      body.pore = pore;
      const DeviceMemoryPlan plan = plan_device_memory(p, 600, {body});
      ASSERT_EQ(plan.block_capacity, 1200);
      const std::size_t table = 4096 * 12 + 1200 * 12 + 1200 * 32 + 8;  // 2 x 1200 -> 4096 slots
      const GridFeatures f{false, false, pore};
      EXPECT_EQ(plan.grid, table + 1200 * grid_channel_block_bytes(p, f));
      const std::size_t sum = p == Precision::Double ? 16 : 8;
      const std::size_t largest = (pore ? 5 : 4) * 64 * sum;  // the seepage sums outgrow the P2G sums
      const std::size_t doubled = 8192 * 12 + 2400 * 12 + 2400 * 32 + 8 + 2400 * grid_channel_block_bytes(p, f);
      EXPECT_EQ(plan.grid_growth, doubled - plan.grid + 1200 * largest + 1200 * (2 * 2 * 4 + 4));
    }
}

TEST(GridChannels, CheckListsTheSetsABodySumsInto) {
  EXPECT_EQ(grid_channels_of_body(GridFeatures{}, GridFeatures{}), "mass, momentum (4)");
  EXPECT_EQ(grid_channels_of_body(GridFeatures{false, true, false}, GridFeatures{true, true, false}),
            "mass, momentum (4) + transported momentum (3: every body sums it when one needs it) + F-bar / node volume sums (2)");
  EXPECT_EQ(grid_channels_of_body(GridFeatures{false, false, true}, GridFeatures{false, true, true}),
            "mass, momentum (4) + seepage channels (5)");
}

// docs/developer_guide.md "Adding a grid channel" shows declarations of kGridSets: each shown line is in the header.
TEST(GridChannels, DeveloperGuideQuotesTheDeclarations) {
  auto read = [](const std::string& path) {
    std::ifstream in(path);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  };
  const std::string guide = read(std::string(FBAR_SOURCE_DIR) + "/docs/developer_guide.md");
  const std::string header = read(std::string(FBAR_SOURCE_DIR) + "/Projects/FBAR/engine/grid_channels.h");
  const std::size_t section = guide.find("## Adding a grid channel");
  ASSERT_NE(section, std::string::npos);
  const std::size_t begin = guide.find("```cpp\n", section);
  ASSERT_NE(begin, std::string::npos);
  const std::size_t end = guide.find("```", begin + 7);
  std::istringstream block(guide.substr(begin + 7, end - begin - 7));
  int lines = 0;
  for (std::string line; std::getline(block, line);) {
    if (line.empty()) continue;
    EXPECT_NE(header.find(line), std::string::npos) << "not in grid_channels.h: " << line;
    ++lines;
  }
  EXPECT_GE(lines, 3);
}

}  // namespace
}  // namespace fbar
