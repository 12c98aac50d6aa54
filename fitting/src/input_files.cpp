// Input-file checks shared by every reader (regular files only, bounded JSON). See input_files.h.
#include "bodyfit/fitting/input_files.h"

#include "bodyfit/fitting/errors.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>

namespace bodyfit
{

namespace
{

const char* fileTypeProblem(mode_t mode)
{
	if (S_ISDIR(mode))
		return "is a directory, not a file";
	if (S_ISFIFO(mode))
		return "is a FIFO (named pipe), not a regular file";
	if (S_ISSOCK(mode))
		return "is a socket, not a regular file";
	if (S_ISCHR(mode))
		return "is a character device, not a regular file";
	if (S_ISBLK(mode))
		return "is a block device, not a regular file";
	if (!S_ISREG(mode))
		return "is not a regular file";
	return nullptr;
}

} // namespace

std::string inputFileProblem(const std::string& path)
{
	if (path.empty())
		return "empty file name";
	struct stat st
	{
	};
	if (::stat(path.c_str(), &st) != 0)
	{
		if (errno == ENOENT)
			return "does not exist";
		if (errno == ENOTDIR)
			return "does not exist (a parent of it is not a directory)";
		return std::string("cannot be opened: ") + std::strerror(errno);
	}
	if (const char* problem = fileTypeProblem(st.st_mode))
		return problem;
	// A regular file now; O_NONBLOCK keeps this open from blocking should it have been swapped for a FIFO since.
	const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
	if (fd < 0)
		return std::string("cannot be opened: ") + std::strerror(errno);
	const bool regular = ::fstat(fd, &st) == 0 && S_ISREG(st.st_mode);
	::close(fd);
	return regular ? "" : "is not a regular file";
}

std::string jsonDepthProblem(std::string_view text, int maxDepth)
{
	int depth = 0;
	const std::size_t n = text.size();
	for (std::size_t i = 0; i < n; ++i)
	{
		const char c = text[i];
		if (c == '"')
		{
			for (++i; i < n && text[i] != '"'; ++i)
				if (text[i] == '\\')
					++i; // the escaped character, whatever it is
		}
		else if (c == '/' && i + 1 < n && text[i + 1] == '/')
		{
			while (i < n && text[i] != '\n')
				++i;
		}
		else if (c == '/' && i + 1 < n && text[i + 1] == '*')
		{
			const std::size_t end = text.find("*/", i + 2);
			i = end == std::string_view::npos ? n : end + 1;
		}
		else if (c == '[' || c == '{')
		{
			if (++depth > maxDepth)
				return "arrays/objects nested deeper than " + std::to_string(maxDepth) + " levels (at byte " +
					   std::to_string(i) + ")";
		}
		else if ((c == ']' || c == '}') && depth > 0)
			--depth;
	}
	return "";
}

std::string readJsonInputFile(const std::string& path, const std::string& what)
{
	const std::string problem = inputFileProblem(path);
	if (!problem.empty())
		throw FormatError(path + ": cannot open " + what + ": " + problem);
	std::ifstream in(path, std::ios::binary);
	if (!in)
		throw FormatError(path + ": cannot open " + what);
	in.seekg(0, std::ios::end);
	const std::streamoff size = in.tellg();
	in.seekg(0, std::ios::beg);
	if (size < 0 || std::size_t(size) > kMaxJsonFileBytes)
		throw FormatError(path + ": " + what + " is larger than " + std::to_string(kMaxJsonFileBytes >> 20) +
						  " MiB (" + std::to_string(size) + " bytes)");
	std::string text(std::size_t(size), '\0');
	if (size > 0 && !in.read(&text[0], size))
		throw FormatError(path + ": read failed");
	const std::string depth = jsonDepthProblem(text);
	if (!depth.empty())
		throw FormatError(path + ": not a usable JSON document: " + depth);
	return text;
}

} // namespace bodyfit
