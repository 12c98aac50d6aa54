// README.md's code for "Using it in your own Bullet scene" is readme_snippet.cpp (compiled into this suite): the
// README must show exactly the text between that file's markers, and the code must run on a bundled fit.
#include "support/paths.h"

#include <catch2/catch.hpp>

#include <fstream>
#include <sstream>
#include <string>

int dropIn(const char* fitFile);

namespace
{

std::string readFile(const std::string& path)
{
	std::ifstream in(path);
	REQUIRE(in.good());
	std::stringstream ss;
	ss << in.rdbuf();
	return ss.str();
}

/// The text strictly between the line containing `begin` and the next line containing `end`.
std::string between(const std::string& text, const std::string& begin, const std::string& end)
{
	const size_t b = text.find(begin);
	REQUIRE(b != std::string::npos);
	const size_t start = text.find('\n', b) + 1;
	const size_t e = text.find(end, start);
	REQUIRE(e != std::string::npos);
	const size_t stop = text.rfind('\n', e) + 1;
	return text.substr(start, stop - start);
}

} // namespace

TEST_CASE("README: the Bullet snippet is readme_snippet.cpp verbatim, and it runs", "[bullet_ext][readme]")
{
	const std::string root = std::string(BODYFIT_ASSET_DIR) + "/../..";
	const std::string readme = readFile(root + "/README.md");
	const size_t section = readme.find("## Using it in your own Bullet scene");
	REQUIRE(section != std::string::npos);
	const std::string shown = between(readme.substr(section), "```cpp", "```");
	const std::string compiled =
		between(readFile(root + "/tests/bullet_ext/readme_snippet.cpp"), "// README snippet begin", "// README snippet end");
	CHECK(shown == compiled);
	CHECK(dropIn(bodyfit_test::assetPath("fits/female_young.json").c_str()) == 0);
}
