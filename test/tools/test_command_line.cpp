// The tools' shared command line: strict numbers, errors that name the flag (exit 2), --help
// (exit 0), nothing left over ignored.
#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <vector>

#include "deep_ois/tools/support/command_line.h"

namespace deep_ois {
namespace {

TEST(ParseStrictNumber, TakesWholeDecimalNumbersOnly) {
  EXPECT_EQ(parseStrictNumber<int>("10"), 10);
  EXPECT_EQ(parseStrictNumber<int>("-3"), -3);
  EXPECT_EQ(parseStrictNumber<int>("+5"), 5);
  for (const char* bad : {"10x", "", " 10", "10 ", "1e3", "0x10", "3.5", "+", "-", "99999999999"}) {
    EXPECT_FALSE(parseStrictNumber<int>(bad)) << "'" << bad << "'";
  }
  EXPECT_EQ(parseStrictNumber<std::uint32_t>("4294967295"), 4294967295u);
  EXPECT_FALSE(parseStrictNumber<std::uint32_t>("4294967296"));
  EXPECT_FALSE(parseStrictNumber<std::uint32_t>("-1"));  // would wrap to 4294967295 with strtoul
  EXPECT_FALSE(parseStrictNumber<std::size_t>("-1"));
}

TEST(ParseStrictNumber, TakesFiniteNumbers) {
  EXPECT_DOUBLE_EQ(*parseStrictNumber<double>("1e-4"), 1e-4);
  EXPECT_DOUBLE_EQ(*parseStrictNumber<double>("-0.01"), -0.01);
  EXPECT_DOUBLE_EQ(*parseStrictNumber<double>(".5"), 0.5);
  for (const char* bad : {"nan", "inf", "-inf", "1e", "0.1s", "", "1,5", "1e999"}) {
    EXPECT_FALSE(parseStrictNumber<double>(bad)) << "'" << bad << "'";
  }
}

TEST(CommaSeparatedNumbers, CountsAndChecksEveryItem) {
  EXPECT_EQ(splitCommaSeparatedNumbers("0,-1,0,-1,0,0,0,0,-1").size(), 9u);
  EXPECT_THROW(splitCommaSeparatedNumbers("1,x,3"), std::invalid_argument);
  EXPECT_THROW(splitCommaSeparatedNumbers("1,2,"), std::invalid_argument);
  std::string nine = "1,0,0,0,1,0,0,0,1", three = "1,2,3", bad = "1,0,0,0,1,0,0,0,y";
  EXPECT_EQ(commaSeparatedNumbers(9)(nine), "");
  EXPECT_NE(commaSeparatedNumbers(9)(three).find("got 3"), std::string::npos);
  EXPECT_NE(commaSeparatedNumbers(9)(bad).find("'y'"), std::string::npos);
}

// A tool with the kinds of flags the package's tools have.
struct ExampleTool {
  ToolCommandLine command_line{"example", "Does an example thing, in one paragraph.",
                               "Exit status: 0 done, 2 usage."};
  std::vector<std::string> bags;
  int epochs = 40;
  double lr = 1e-4;
  std::size_t max_pairs = 0;
  std::string ois = "off";
  bool quiet = false;

  ExampleTool() {
    CLI::App& app = command_line.app();
    app.add_option("--bags", bags, "the recordings")->required()->type_name("FILE.bag");
    command_line.addNumber("--epochs", epochs, "training epochs");
    command_line.addNumber("--lr", lr, "learning rate");
    command_line.addNumber("--max-pairs", max_pairs, "at most this many pairs (0: all)");
    app.add_option("--ois", ois, "lens shift")->check(oneOf({"on", "off"}))->capture_default_str();
    app.add_flag("--quiet", quiet, "no progress bar");
  }

  // The exit status parse() asks for (-1: go on) and what it printed on stdout and stderr.
  int run(std::vector<std::string> arguments, std::string* out = nullptr,
          std::string* err = nullptr) {
    arguments.insert(arguments.begin(), "example");
    ::testing::internal::CaptureStdout();
    ::testing::internal::CaptureStderr();
    const std::optional<int> status = command_line.parse(arguments);
    const std::string printed_out = ::testing::internal::GetCapturedStdout();
    const std::string printed_err = ::testing::internal::GetCapturedStderr();
    if (out) *out = printed_out;
    if (err) *err = printed_err;
    return status ? *status : -1;
  }
};

TEST(ToolCommandLine, ParsesValuesListsAndFlags) {
  ExampleTool tool;
  ASSERT_EQ(tool.run({"--bags", "a.bag", "b.bag", "--epochs", "10", "--lr", "1e-3", "--ois", "on",
                      "--quiet"}),
            -1);
  EXPECT_EQ(tool.bags, (std::vector<std::string>{"a.bag", "b.bag"}));
  EXPECT_EQ(tool.epochs, 10);
  EXPECT_DOUBLE_EQ(tool.lr, 1e-3);
  EXPECT_EQ(tool.ois, "on");
  EXPECT_TRUE(tool.quiet);
}

TEST(ToolCommandLine, HelpPrintsTheDescriptionAndEveryFlagWithItsDefaultAndExitsZero) {
  ExampleTool tool;
  std::string out;
  EXPECT_EQ(tool.run({"--help"}, &out), 0);
  for (const char* expected :
       {"Does an example thing, in one paragraph.", "Usage: example", "--bags FILE.bag", "REQUIRED",
        "--epochs INT=40", "--lr FLOAT=0.0001", "--ois TEXT=off", "--quiet",
        "Exit status: 0 done, 2 usage."}) {
    EXPECT_NE(out.find(expected), std::string::npos) << expected << " not in:\n" << out;
  }
}

TEST(ToolCommandLine, AMalformedNumberIsAnErrorNamingTheFlag) {
  ExampleTool tool;
  std::string err;
  EXPECT_EQ(tool.run({"--bags", "a.bag", "--epochs", "10x"}, nullptr, &err), kUsageExitStatus);
  EXPECT_EQ(err.rfind("example: --epochs: Value 10x could not be converted", 0), 0u) << err;
  EXPECT_EQ(tool.run({"--bags", "a.bag", "--lr", "nan"}, nullptr, &err), kUsageExitStatus);
  EXPECT_EQ(err.rfind("example: --lr: Value nan could not be converted", 0), 0u) << err;
  EXPECT_EQ(tool.run({"--bags", "a.bag", "--max-pairs", "-1"}, nullptr, &err), kUsageExitStatus);
  EXPECT_EQ(err.rfind("example: --max-pairs:", 0), 0u) << err;
  EXPECT_EQ(tool.run({"--bags", "a.bag", "--epochs=7y"}, nullptr, &err), kUsageExitStatus);
  EXPECT_EQ(err.rfind("example: --epochs:", 0), 0u) << err;
}

TEST(ToolCommandLine, UnknownFlagsMissingValuesAndLeftoversAreErrors) {
  std::string err;
  EXPECT_EQ(ExampleTool().run({"--bags", "a.bag", "--epoch", "10"}, nullptr, &err),
            kUsageExitStatus);
  EXPECT_EQ(err.rfind("example: --epoch: unknown flag", 0), 0u) << err;
  // A trailing flag without its value is not ignored.
  EXPECT_EQ(ExampleTool().run({"--bags", "a.bag", "--epochs"}, nullptr, &err), kUsageExitStatus);
  EXPECT_EQ(err.rfind("example: --epochs:", 0), 0u) << err;
  // Nor is a value after a flag that takes none.
  EXPECT_EQ(ExampleTool().run({"--bags", "a.bag", "--quiet", "yes"}, nullptr, &err),
            kUsageExitStatus);
  EXPECT_NE(err.find("yes"), std::string::npos) << err;
  EXPECT_EQ(ExampleTool().run({"--bags", "a.bag", "--ois", "maybe"}, nullptr, &err),
            kUsageExitStatus);
  EXPECT_EQ(err.rfind("example: --ois: must be on or off, got 'maybe'", 0), 0u) << err;
  EXPECT_EQ(ExampleTool().run({"--epochs", "3"}, nullptr, &err), kUsageExitStatus);
  EXPECT_EQ(err.rfind("example: --bags is required", 0), 0u) << err;
}

TEST(ToolCommandLine, WithoutArgumentsAToolWithRequiredFlagsPrintsItsHelpOnStderr) {
  std::string out, err;
  EXPECT_EQ(ExampleTool().run({}, &out, &err), kUsageExitStatus);
  EXPECT_EQ(out, "");
  EXPECT_NE(err.find("Usage: example"), std::string::npos) << err;
}

TEST(ToolCommandLine, UsageErrorNamesTheToolAndReturnsTwo) {
  ExampleTool tool;
  ::testing::internal::CaptureStderr();
  EXPECT_EQ(tool.command_line.usageError("--camera applies to --annotations only"),
            kUsageExitStatus);
  const std::string err = ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(err.rfind("example: --camera applies to --annotations only\n", 0), 0u) << err;
}

TEST(ToolCommandLine, ExistingFileCheckNamesTheFlag) {
  ToolCommandLine command_line("example", "Reads a file.");
  std::string path;
  command_line.app().add_option("--bag", path, "input")->check(CLI::ExistingFile);
  ::testing::internal::CaptureStderr();
  const std::optional<int> status =
      command_line.parse({"example", "--bag", ::testing::TempDir() + "/no_such_file.bag"});
  const std::string err = ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(status, kUsageExitStatus);
  EXPECT_EQ(err.rfind("example: --bag:", 0), 0u) << err;
  EXPECT_NE(err.find("no_such_file.bag"), std::string::npos) << err;
}

}  // namespace
}  // namespace deep_ois
