// Text helpers shared by the input checks of each format (input_checks*.cpp); private to simcore.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

namespace rehearse::simcore::checks::detail {

// A number as the messages write it: whole numbers in full, others to 4 significant digits.
std::string num(double v);

bool isSpace(char c);

std::string_view trim(std::string_view s);

std::string lowerCopy(std::string_view s);

// Splits on whitespace.
std::vector<std::string_view> words(std::string_view s);

bool toLong(std::string_view s, long long& v);

bool toDouble(std::string_view s, double& v);

// Reads the next line of `s` from `pos` (without its end of line); false at the end.
bool nextLine(std::string_view s, std::size_t& pos, std::string_view& line);

std::string plural(double n, const std::string& word);

}  // namespace rehearse::simcore::checks::detail
