// A small TeX-to-HTML converter for block labels such as "$\mu_n + K\,(h_n - h)$".
// It covers what block diagrams use: Greek letters, sub- and superscripts, spacing,
// \dot/\hat/\bar accents, \frac (written a/b) and \mathrm; anything else is shown as typed.

const GREEK = {
  alpha: "α", beta: "β", gamma: "γ", delta: "δ", epsilon: "ε", varepsilon: "ε", zeta: "ζ",
  eta: "η", theta: "θ", vartheta: "ϑ", iota: "ι", kappa: "κ", lambda: "λ", mu: "μ", nu: "ν",
  xi: "ξ", pi: "π", rho: "ρ", sigma: "σ", tau: "τ", upsilon: "υ", phi: "φ", varphi: "φ",
  chi: "χ", psi: "ψ", omega: "ω", Gamma: "Γ", Delta: "Δ", Theta: "Θ", Lambda: "Λ", Xi: "Ξ",
  Pi: "Π", Sigma: "Σ", Phi: "Φ", Psi: "Ψ", Omega: "Ω", cdot: "·", times: "×", int: "∫",
  sum: "∑", infty: "∞", leq: "≤", geq: "≥", le: "≤", ge: "≥", pm: "±", to: "→",
  rightarrow: "→", partial: "∂", nabla: "∇", approx: "≈", neq: "≠",
};
const SPACE = { ",": "\u2009", ";": "\u2005", ":": "\u2005", "!": "", " ": " ", quad: "\u2003" };
const ACCENT = { dot: "\u0307", ddot: "\u0308", hat: "\u0302", bar: "\u0304", tilde: "\u0303",
  vec: "\u20d7" };

function escape(s) {
  return s.replace(/&/g, "&amp;").replace(/</g, "&lt;").replace(/>/g, "&gt;");
}

// read one argument at i: a {group} or a single token; returns [html, next index]
function argument(src, i) {
  if (src[i] === "{") {
    let depth = 1, j = i + 1;
    while (j < src.length && depth) {
      if (src[j] === "{") depth++;
      else if (src[j] === "}") depth--;
      j++;
    }
    return [math(src.slice(i + 1, j - 1)), j];
  }
  if (src[i] === "\\") {
    const m = /^\\([A-Za-z]+|.)/.exec(src.slice(i));
    if (!m) return [escape(src[i]), i + 1];  // a lone backslash at the end
    return [math(m[0]), i + m[0].length];
  }
  return [escape(src[i] || ""), i + 1];
}

// A table's own entry: a label's "\constructor" or "\toString" is text, not a member every
// object inherits (which "name in GREEK" found, and drew as its source)
function own(table, name) {
  return Object.prototype.hasOwnProperty.call(table, name);
}

function math(src) {
  let out = "", i = 0;
  while (i < src.length) {
    const c = src[i];
    if (c === "\\") {
      const m = /^\\([A-Za-z]+|.)/.exec(src.slice(i));
      if (!m) { out += escape(c); i++; continue; }  // a lone backslash at the end
      const name = m[1];
      i += m[0].length;
      if (own(GREEK, name)) out += GREEK[name];
      else if (own(SPACE, name)) out += SPACE[name];
      else if (own(ACCENT, name)) {
        const [a, j] = argument(src, i);
        out += a + ACCENT[name];
        i = j;
      } else if (name === "frac") {
        const [a, j] = argument(src, i);
        const [b, k] = argument(src, j);
        out += `${a}/${b}`;
        i = k;
      } else if (name === "mathrm" || name === "text" || name === "operatorname") {
        const [a, j] = argument(src, i);
        out += `<span class="ck-upright">${a}</span>`;
        i = j;
      } else if (name === "left" || name === "right") {
        continue;
      } else out += escape(m[0]);
    } else if (c === "_" || c === "^") {
      const [a, j] = argument(src, i + 1);
      out += c === "_" ? `<sub>${a}</sub>` : `<sup>${a}</sup>`;
      i = j;
    } else if (c === "{" || c === "}") {
      i++;
    } else if (c === "-") {
      out += "\u2212";
      i++;
    } else {
      out += escape(c);
      i++;
    }
  }
  return out;
}

// HTML for a label: text outside $...$ as typed, math inside converted
export function texToHtml(label) {
  const parts = String(label).split("$");
  return parts.map((part, k) => (k % 2 ? `<span class="ck-math">${math(part)}</span>`
    : escape(part))).join("");
}
