// dejag completion bash: a bash completion script made from the command tree itself, so it never lags
// behind a new subcommand or flag. `cmake --install` installs its output as
// share/bash-completion/completions/dejag.
#include <cstdio>
#include <string>

#include "app/cli.h"
#include "app/commands.h"
#include "base/error.h"

namespace dejag::cli {
namespace {

// Every visible subcommand path below `command`, with its subcommands' and options' names, as the arms of
// a bash `case` on the path.
void caseArms(const CLI::App& command, const std::string& path, std::string& out) {
    std::string subs, opts;
    for (const CLI::App* sub :
         command.get_subcommands([](const CLI::App* a) { return !a->get_group().empty(); }))
        subs += (subs.empty() ? "" : " ") + sub->get_name();
    for (const CLI::Option* option : command.get_options()) {
        for (const std::string& name : option->get_lnames()) opts += (opts.empty() ? "--" : " --") + name;
        for (const std::string& name : option->get_snames()) opts += (opts.empty() ? "-" : " -") + name;
    }
    if (path == "bench nn")  // a prefix command: its flags are dejag-bench-nn's
        opts = "--json --repeat --thread-counts --threads --case --help";
    out += "        \"" + path + "\") subs=\"" + subs + "\"; opts=\"" + opts + "\" ;;\n";
    for (const CLI::App* sub :
         command.get_subcommands([](const CLI::App* a) { return !a->get_group().empty(); }))
        caseArms(*sub, path.empty() ? sub->get_name() : path + " " + sub->get_name(), out);
}

std::string bashScript(const CLI::App& root) {
    std::string arms;
    caseArms(root, "", arms);
    return "# bash completion for dejag, made by `dejag completion bash`\n"
           "_dejag_lists() {\n"
           "    subs=\"\" opts=\"\"\n"
           "    case \"$1\" in\n" +
           arms +
           "    esac\n"
           "}\n"
           "_dejag() {\n"
           "    local cur=\"${COMP_WORDS[COMP_CWORD]}\" path=\"\" word i subs opts\n"
           "    for ((i = 1; i < COMP_CWORD; i++)); do\n"
           "        word=\"${COMP_WORDS[i]}\"\n"
           "        [[ \"$word\" == -* ]] && continue\n"
           "        _dejag_lists \"$path\"\n"
           "        [[ \" $subs \" == *\" $word \"* ]] && path=\"${path:+$path }$word\"\n"
           "    done\n"
           "    _dejag_lists \"$path\"\n"
           "    if [[ \"$cur\" == -* ]]; then\n"
           "        COMPREPLY=($(compgen -W \"$opts\" -- \"$cur\"))\n"
           "    elif [[ -n \"$subs\" ]]; then\n"
           "        COMPREPLY=($(compgen -W \"$subs\" -- \"$cur\"))\n"
           "    else\n"
           "        COMPREPLY=($(compgen -f -- \"$cur\"))\n"
           "    fi\n"
           "}\n"
           "complete -o filenames -F _dejag dejag\n";
}

}  // namespace

void registerCompletionCommand(CLI::App& app) {
    auto shell = std::make_shared<std::string>();
    CLI::App* command =
        app.add_subcommand("completion", "print a shell completion script: dejag completion bash > FILE");
    command->add_option("shell", *shell, "the shell: bash")->required();
    command->callback([&app, shell] {
        if (*shell != "bash") throw Error("'" + *shell + "' is not a shell dejag completes (bash)");
        std::fputs(bashScript(app).c_str(), stdout);
    });
}

}  // namespace dejag::cli
