#pragma once
// Paths to the data the tests read: tests/data (small crafted files) and demos/assets (bundled bodies).
#include <string>

namespace bodyfit_test
{
inline std::string dataPath(const std::string& name) { return std::string(BODYFIT_TEST_DATA_DIR) + "/" + name; }
inline std::string assetPath(const std::string& name) { return std::string(BODYFIT_ASSET_DIR) + "/" + name; }
} // namespace bodyfit_test
