// dejag: one binary, a subcommand per stage. Every error is one line on stderr and exit code 2.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <exception>
#include <iostream>
#include <string>
#include <thread>
#include <vector>

#include "app/cli.h"
#include "app/commands.h"
#ifdef DEJAG_WITH_MPI
#include "app/mpi.h"
#endif
#include "base/communicator.h"
#include "base/error.h"
#include "base/files.h"
#include "base/simd.h"
#include "base/thread_pool.h"

namespace {

std::string commandPath(const CLI::App& app) {
    std::string path = "dejag";
    const CLI::App* current = &app;
    while (true) {
        auto selected = current->get_subcommands();
        if (selected.empty()) break;
        current = selected.front();
        path += " " + current->get_name();
    }
    return path;
}

// `dejag --version`: the version, how this binary was built, and what the CPU it runs on offers.
std::string versionText() {
#ifndef DEJAG_VERSION
#define DEJAG_VERSION "unknown"
#endif
#ifndef DEJAG_BUILD_TYPE
#define DEJAG_BUILD_TYPE ""
#endif
    std::string build = DEJAG_BUILD_TYPE;
    if (build.empty()) build = "unnamed";
#if defined(__clang__)
    const std::string compiler = "clang " __clang_version__;
#elif defined(__GNUC__)
    const std::string compiler = "g++ " __VERSION__;
#else
    const std::string compiler = "an unknown compiler";
#endif
    std::string levels;
    for (int level = int(dejag::cpuSimdLevel()); level >= 0; --level)
        levels += std::string(levels.empty() ? "" : ", ") + dejag::simdLevelName(dejag::SimdLevel(level));
    return std::string("dejag ") + DEJAG_VERSION + "\nbuild: " + build + ", " + compiler +
           "\nSIMD on this CPU: " + levels + (dejag::bf16Available() ? " (with AVX-512 BF16)" : "") +
           "; DEJAG_SIMD or --simd chooses one";
}

}  // namespace

namespace {

int run(int argc, char** argv) {
    dejag::flushDenormalsOnThisThread();
    dejag::installTemporaryFileCleanup();
    for (int i = 0; i < argc; ++i) {
        std::string word = i == 0 ? std::string("dejag") : std::string(argv[i]);
        if (word.find_first_of(" \t'\"*?[]$&;|<>(){}!~`") != std::string::npos) word = "'" + word + "'";
        dejag::cli::invocation() += (i ? " " : "") + word;
    }
    CLI::App app{
        "dejag: learns to remove aliasing from rendered frames.\n"
        "Each subcommand has --help. Errors: one line on stderr, exit code 2."};
    app.name("dejag");
    app.require_subcommand(1);
    app.set_version_flag(  // (made when asked: a bad DEJAG_SIMD is then one error line)
        "--version", [] { return versionText(); }, "print the version, the build and the CPU's SIMD levels");
    dejag::cli::registerRenderCommand(app);
    dejag::cli::registerDataCommand(app);
    dejag::cli::registerTrainCommand(app);
    dejag::cli::registerFilterCommand(app);
    dejag::cli::registerExportCommand(app);
    dejag::cli::registerViewCommand(app);
    dejag::cli::registerMetricsCommand(app);
    dejag::cli::registerBenchCommand(app);
    dejag::cli::registerDemoCommand(app);
    dejag::cli::registerCompletionCommand(app);
    dejag::cli::guardNumericOptions(app);
    dejag::cli::finishHelp(app);

    // A job of several processes runs only the commands that share their work between them; any other
    // would run whole on every rank, each writing the same files.
    if (dejag::communicator().size() > 1) {
        std::vector<std::string> words;
        for (int i = 1; i < argc; ++i)
            if (argv[i][0] != '-') words.push_back(argv[i]);
        const bool help = std::any_of(argv + 1, argv + argc, [](const char* a) {
            return std::string(a) == "--help" || std::string(a) == "-h" || std::string(a) == "--version";
        });
        const std::string command = words.empty() ? std::string() : words[0];
        const std::string sub = words.size() > 1 ? words[1] : std::string();
        const bool shared = (command == "train" && sub != "export") ||
                            (command == "data" && sub == "generate") ||
                            (command == "bench" && sub == "collective");
        if (!help && !shared) {
            if (dejag::communicator().rank() == 0)
                std::fprintf(
                    stderr,
                    "dejag-mpi: '%s' would run whole on every rank; in a job of several processes only "
                    "'train', 'data generate' and 'bench collective' share their work (run it with "
                    "dejag)\n",
                    (command + (command == "data" || command == "bench" || sub == "export" ? " " + sub : ""))
                        .c_str());
            return 2;
        }
    }

    try {
        app.parse(argc, argv);
    } catch (const CLI::Success& success) {
        return app.exit(success);  // --help, --version
    } catch (const CLI::ParseError& error) {
        std::string message = error.what();
        if (app.get_subcommands().empty()) {
            std::string names;
            for (const CLI::App* command : app.get_subcommands([](const CLI::App*) { return true; }))
                names += (names.empty() ? "" : ", ") + command->get_name();
            const bool named = argc > 1 && argv[1][0] != '-';
            message = named ? "unknown subcommand '" + std::string(argv[1]) + "'; choose one of: " + names
                            : "choose a subcommand: " + names;
        }
        // (The same on every rank of a job: rank 0 says it.)
        if (dejag::communicator().rank() == 0)
            std::fprintf(stderr, "%s: %s (see --help)\n", commandPath(app).c_str(), message.c_str());
        return 2;
    } catch (const dejag::ReportedElsewhere& reported) {
        return reported.code;
    } catch (const dejag::Error& error) {
        // In a job, an error every rank meets (a bad argument, a missing file) is said by rank 0, whose
        // end ends the others: they wait a moment before saying theirs, an error of their own.
        if (dejag::communicator().rank() > 0) std::this_thread::sleep_for(std::chrono::milliseconds(500));
        std::fprintf(stderr, "%s%s: %s\n", commandPath(app).c_str(),
                     dejag::communicator().rankLabel().c_str(), error.what());
        return 2;
    } catch (const std::exception& error) {
        std::fprintf(stderr, "%s%s: internal error: %s\n", commandPath(app).c_str(),
                     dejag::communicator().rankLabel().c_str(), error.what());
        return 3;
    }
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
#ifdef DEJAG_WITH_MPI
    // dejag-mpi: every rank runs the command; the stages that share work ask base/communicator.h.
    dejag::cli::MpiSession mpi(argc, argv);
    return mpi.finish(run(argc, argv));
#else
    return run(argc, argv);
#endif
}
