// Runs a Flamenco job-type script the way the Manager does (compileJob(job) with the `author` API in scope),
// against a small mock of that API, and prints the authored tasks as JSON.
// Usage: node flamenco_mock.js JOB_TYPE.js '{"setting": "value"}'
"use strict";
const fs = require("fs");
const vm = require("vm");

const [file, settingsJson] = process.argv.slice(2);
const code = fs.readFileSync(file, "utf8");
const added = [];
const author = {
  Task(name, type) {
    if (typeof name !== "string" || typeof type !== "string") throw new Error("Task(name, type) needs strings");
    return {
      name,
      type,
      commands: [],
      deps: [],
      addCommand(c) {
        this.commands.push(c);
      },
      addDependency(d) {
        if (!added.includes(d)) throw new Error(`${this.name}: dependency on ${d.name}, not added to the job yet`);
        this.deps.push(d);
      },
    };
  },
  Command(name, params) {
    return { name, params };
  },
};
const ctx = vm.createContext({ author, print: (...a) => console.error(...a) });
vm.runInContext(code + "\n;globalThis.__crease = { JOB_TYPE, compileJob };", ctx, { filename: file });
const { JOB_TYPE, compileJob } = ctx.__crease;
const settings = JSON.parse(settingsJson || "{}");
for (const s of JOB_TYPE.settings) {
  if (!(s.key in settings) && "default" in s) settings[s.key] = s.default;
  if (s.required && !(s.key in settings)) throw new Error(`setting ${s.key} is required`);
}
const job = {
  settings,
  addTask(t) {
    added.push(t);
  },
};
compileJob(job);
console.log(
  JSON.stringify({
    label: JOB_TYPE.label,
    tasks: added.map((t) => ({ name: t.name, type: t.type, commands: t.commands, deps: t.deps.map((d) => d.name) })),
  })
);
