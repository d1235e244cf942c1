#pragma once
// Save-then-load checks for options structs (MRPT CLoadableOptions).

#include <gtest/gtest.h>
#include <mrpt/config/CConfigFileMemory.h>

#include <string>

namespace lookup::options_testing {

/// `a` saved, loaded into a default-constructed T and saved again gives the same text; `a`
/// must differ from the defaults, so the load has something to restore.
template <class T>
void expectRoundTrip(const T& a, const std::string& section) {
    mrpt::config::CConfigFileMemory first, second, defaults;
    a.saveToConfigFile(first, section);
    T b;
    b.loadFromConfigFile(first, section);
    b.saveToConfigFile(second, section);
    EXPECT_EQ(first.getContent(), second.getContent()) << section;
    T().saveToConfigFile(defaults, section);
    EXPECT_NE(first.getContent(), defaults.getContent()) << section << ": holds the defaults";
}

}  // namespace lookup::options_testing
