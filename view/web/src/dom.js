// The page's elements. What the server sends is data, never markup: text goes in as text
// nodes (textContent, `el`'s children), so a hostile name cannot add elements or scripts.

/** The element with this id (index.html has them all). @type {(id: string) => any} */
export const $ = (id) => document.getElementById(id);

/**
 * A new element: `el('option', { value: '1', selected: true }, 'steel')`. Properties are set
 * as properties (`className`, `value`, `title`, `type`, `step`…); children are nodes or
 * strings (text).
 * @param {string} tag
 * @param {Record<string, any>} [props]
 * @param {...(Node|string)} children
 * @returns {any}
 */
export function el(tag, props = {}, ...children) {
  const e = document.createElement(tag);
  Object.assign(e, props);
  e.append(...children);
  return e;
}
