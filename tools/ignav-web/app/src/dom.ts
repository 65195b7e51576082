// Small DOM helpers the panels share: an element by id (index.html must have it), an element with
// attributes and children, and a definition list of facts.

export function byId<T extends HTMLElement = HTMLElement>(id: string): T {
  const element = document.getElementById(id);
  if (!element) throw new Error(`index.html has no #${id}`);
  return element as T;
}

export function el<K extends keyof HTMLElementTagNameMap>(
  tag: K,
  attributes: Record<string, string> = {},
  ...children: (Node | string)[]
): HTMLElementTagNameMap[K] {
  const element = document.createElement(tag);
  for (const [name, value] of Object.entries(attributes)) element.setAttribute(name, value);
  element.append(...children);
  return element;
}

// Definition-list rows: [term, value, data-testid?, tooltip?].
export function facts(rows: [string, string, string?, string?][]): HTMLElement {
  const dl = el("dl");
  for (const [term, value, testid, title] of rows) {
    const attributes: Record<string, string> = {};
    if (testid) attributes["data-testid"] = testid;
    if (title) attributes.title = title;
    dl.append(el("dt", {}, term), el("dd", attributes, value));
  }
  return dl;
}

// What a panel showed last, per slot: a panel is rebuilt only when what it shows has changed, so
// that a stream of updates neither flickers it nor swallows a click on it.
export class ShownSlots {
  private readonly keys = new Map<string, string>();

  // True when `value` differs from what `slot` showed last (and remembers it).
  changed(slot: string, value: unknown): boolean {
    const key = JSON.stringify(value);
    if (this.keys.get(slot) === key) return false;
    this.keys.set(slot, key);
    return true;
  }
}

// A button that acts on a click and nothing else (not also its row's "go to").
export function actionButton(
  label: string,
  testid: string,
  enabled: boolean,
  title: string,
  act: () => void,
): HTMLButtonElement {
  const b = el("button", { "data-testid": testid, title }, label);
  b.disabled = !enabled;
  b.addEventListener("click", (event) => {
    event.stopPropagation();
    act();
  });
  return b;
}
