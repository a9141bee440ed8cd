#include "training/plot.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "engine/io/file_io.h"
#include "tests/unit/offline/render/xml_dom.h"

namespace ss::train {
namespace {

namespace fs = std::filesystem;

void write(const fs::path& p, const std::string& text) { std::ofstream(p) << text; }

TEST(PlotRun, OnePanelPerHeadWithTheTrainLineAndTheValDots) {
  const fs::path dir = fs::temp_directory_path() / ("ss_plot_" + std::to_string(getpid()));
  fs::create_directories(dir);
  const std::string cols = "step,motion_loss,light_loss,type_loss,end_loss,segment_loss,state_loss\n";
  write(dir / "train_log.csv", cols + "10,3,1,1,1,2,2\n20,2.5,0.9,0.8,0.7,1.5,1.8\n30,2,0.8,0.7,0.6,1.2,1.5\n");
  write(dir / "val_log.csv", cols + "20,2.6,0.95,0.85,0.75,1.6,1.9\n");
  const std::string out = (dir / "curves.svg").string();
  ASSERT_TRUE(plot_run(dir.string(), out).ok());
  auto text = file_read_all(out);
  ASSERT_TRUE(text.ok());
  std::string error;
  auto root = ss::testing::XmlReader::parse(*text, &error);
  ASSERT_TRUE(root) << error;
  EXPECT_EQ(root->all("path").size(), 6u);    // the train line of each head
  EXPECT_EQ(root->all("circle").size(), 6u);  // one val point of each head
  EXPECT_EQ(root->all("path")[0]->attr("d").rfind("M", 0), 0u);
  EXPECT_NE(text->find("Steps 0-30."), std::string::npos);
  // A train log without rows is an error, not an empty picture.
  write(dir / "train_log.csv", cols);
  EXPECT_FALSE(plot_run(dir.string(), out).ok());
  fs::remove_all(dir);
}

}  // namespace
}  // namespace ss::train
