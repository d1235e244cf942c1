#include "lookup/common/options_table.h"

#include <algorithm>
#include <cstdlib>
#include <limits>
#include <sstream>

namespace lookup::common {
namespace {

// The shortest text, from 12 significant digits up, that reads back as exactly `v` (12 keeps
// the saved files readable; more only where a value needs them).
std::string doubleText(double v) {
    std::string text;
    for (int precision = 12; precision <= 17; ++precision) {
        std::ostringstream os;
        os.precision(precision);
        os << v;
        text = os.str();
        if (std::strtod(text.c_str(), nullptr) == v) break;
    }
    return text;
}

// The check of a number against [min, max], or none when the range is the type's own.
template <class T>
std::function<void(OptionsCheck&)> rangeCheck(const std::string& key, const T& v, T min, T max) {
    if (min == std::numeric_limits<T>::lowest() && max == std::numeric_limits<T>::max()) return {};
    return [key, &v, min, max, expectation = "in " + rangeText(min, max)](OptionsCheck& c) {
        c.require(v >= min && v <= max, key, expectation);
    };
}

std::string joined(const std::vector<std::string>& names) {
    std::string out;
    for (std::size_t i = 0; i < names.size(); ++i) {
        out += (i == 0 ? "" : ", ") + names[i];
    }
    return out;
}

std::uint64_t parseUnsigned(const IniSection& s, const std::string& key, const std::string& text,
                            std::uint64_t min, std::uint64_t max) {
    std::size_t used = 0;
    std::uint64_t v = 0;
    try {
        v = std::stoull(text, &used);
    } catch (const std::exception&) {
        used = 0;
    }
    if (used != text.size() || text[0] == '-') {
        throw ConfigError(s.where(key) + "'" + text + "' is not a non-negative integer");
    }
    if (v < min || v > max) {
        throw ConfigError(s.where(key) + text + " is out of range [" + std::to_string(min) + ", " +
                          std::to_string(max) + "]");
    }
    return v;
}

}  // namespace

OptionsTable& OptionsTable::addEntry(std::string key, std::function<void(const IniSection&)> load,
                                     std::function<std::string()> text,
                                     std::function<void(OptionsCheck&)> check) {
    entries_.push_back({std::move(key), std::move(load), std::move(text), {}, std::move(check)});
    return *this;
}

OptionsTable& OptionsTable::add(const std::string& key, double& v, double min, double max) {
    return addEntry(
        key, [&v, key, min, max](const IniSection& s) { v = s.getDouble(key, v, min, max); },
        [&v] { return doubleText(v); }, rangeCheck(key, v, min, max));
}

OptionsTable& OptionsTable::add(const std::string& key, int& v, int min, int max) {
    return addEntry(
        key, [&v, key, min, max](const IniSection& s) { v = s.getInt(key, v, min, max); },
        [&v] { return std::to_string(v); }, rangeCheck(key, v, min, max));
}

OptionsTable& OptionsTable::add(const std::string& key, std::uint64_t& v, std::uint64_t min,
                                std::uint64_t max) {
    return addEntry(
        key,
        [&v, key, min, max](const IniSection& s) {
            const std::string text = s.getString(key, "");
            if (!text.empty()) v = parseUnsigned(s, key, text, min, max);
        },
        [&v] { return std::to_string(v); }, rangeCheck(key, v, min, max));
}

OptionsTable& OptionsTable::add(const std::string& key, bool& v) {
    return addEntry(
        key, [&v, key](const IniSection& s) { v = s.getBool(key, v); },
        [&v] { return std::string(v ? "true" : "false"); });
}

OptionsTable& OptionsTable::add(const std::string& key, std::string& v) {
    return addEntry(
        key, [&v, key](const IniSection& s) { v = s.getString(key, v); }, [&v] { return v; });
}

OptionsTable& OptionsTable::addChoice(const std::string& key, std::vector<std::string> names,
                                      std::function<std::size_t()> get,
                                      std::function<void(std::size_t)> set) {
    return addEntry(
        key,
        [key, names, set](const IniSection& s) {
            if (!s.has(key)) return;
            const std::string text = s.getString(key, "");
            const auto it = std::find(names.begin(), names.end(), text);
            if (it == names.end()) {
                throw ConfigError(s.where(key) + "'" + text + "' is not one of " + joined(names));
            }
            set(static_cast<std::size_t>(it - names.begin()));
        },
        [names, get] { return names.at(get()); });
}

void OptionsTable::saveOnlyIf(std::function<bool()> save_if) {
    entries_.back().save_if = std::move(save_if);
}

std::vector<std::string> OptionsTable::keys() const {
    std::vector<std::string> out;
    for (const auto& e : entries_) out.push_back(e.key);
    return out;
}

void OptionsTable::load(const IniSection& section) const {
    section.rejectUnknownKeys(keys());
    for (const auto& e : entries_) e.load(section);
}

void OptionsTable::load(const mrpt::config::CConfigFileBase& source,
                        const std::string& section) const {
    load(IniSection(source, section));
}

void OptionsTable::save(mrpt::config::CConfigFileBase& target, const std::string& section) const {
    for (const auto& e : entries_) {
        if (!e.save_if || e.save_if()) target.write(section, e.key, e.text());
    }
}

void OptionsTable::checkRanges(OptionsCheck& c) const {
    for (const auto& e : entries_) {
        if (e.check) e.check(c);
    }
}

void rejectUnknownSections(const mrpt::config::CConfigFileBase& source,
                           const std::vector<std::string>& known) {
    const auto matches = [](const std::string& pattern, const std::string& name) {
        if (!pattern.empty() && pattern.back() == '*') {
            return name.rfind(pattern.substr(0, pattern.size() - 1), 0) == 0;
        }
        return pattern == name;
    };
    std::vector<std::string> sections;
    source.getAllSections(sections);
    for (const auto& s : sections) {
        if (s.empty()) continue;
        const bool ok = std::any_of(known.begin(), known.end(),
                                    [&](const std::string& k) { return matches(k, s); });
        if (!ok) {
            std::string list;
            for (const auto& k : known) list += (list.empty() ? "" : ", ") + k;
            throw ConfigError(configSourceName(source) + " [" + s +
                              "]: unknown section (known: " + list + ")");
        }
    }
}

}  // namespace lookup::common
